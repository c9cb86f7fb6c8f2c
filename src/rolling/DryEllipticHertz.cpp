#include "rolling/DryEllipticHertz.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace ehlsim {

namespace {

/// Below this |D - 1| the contact is the ball's: the bisection's K - E would
/// lose its digits (K - E ~ pi e^2 / 4 with e^2 ~ |D - 1|), while the semi-axes
/// move by about |D - 1| / 3.
constexpr double kCircularWithin = 1e-9;

/// Bisection steps on the eccentricity: 60 halve [0, 1) to below 1e-18.
constexpr int kBisectionSteps = 60;

}  // namespace

// Hertz theory of elliptic contacts (e.g. Johnson, Contact Mechanics, 3.5):
// with the major semi-axis A, the minor B and e^2 = 1 - B^2/A^2, the gap
// coefficient across the major axis over that along it is
// (E(e)/(1 - e^2) - K(e)) / (K(e) - E(e)), which grows with e from 1.  The
// load and the coefficient along the major axis, here
// c_major = (2/pi^2) pi p0 B (K - E)/(e^2 A^2), give
// A^3 = 2 (K - E)/(pi e^2 c_major) with p0 A B = 1.
EllipticHertzContact dry_elliptic_hertz(double D) {
  if (std::abs(D - 1.0) < kCircularWithin) return {1.0, 1.0, 1.0};
  const double ratio = std::max(D, 1.0 / D);
  const auto coefficient_ratio = [](double e) {
    const double K = std::comp_ellint_1(e), E = std::comp_ellint_2(e);
    return (E / (1.0 - e * e) - K) / (K - E);
  };
  double lo = 0.0, hi = 1.0;
  for (int k = 0; k < kBisectionSteps; ++k) {
    const double mid = 0.5 * (lo + hi);
    (coefficient_ratio(mid) < ratio ? lo : hi) = mid;
  }
  const double e = 0.5 * (lo + hi);
  const double K = std::comp_ellint_1(e), E = std::comp_ellint_2(e);
  const double c_major = 0.5 * std::min(1.0, D);
  const double major = std::cbrt(2.0 * (K - E) / (std::numbers::pi * e * e * c_major));
  const double minor = major * std::sqrt(1.0 - e * e);
  EllipticHertzContact hz;
  hz.ax = D >= 1.0 ? major : minor;
  hz.ay = D >= 1.0 ? minor : major;
  hz.p0 = 1.0 / (hz.ax * hz.ay);
  return hz;
}

}  // namespace ehlsim
