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

/// The bisection runs on ln(B / A), the minor over the major semi-axis, from
/// this bound (D or 1 / D near 1e298: B^2 / A^2 stays a normal double) to 0.
constexpr double kSmallestAxisRatio = 1e-150;

/// Bisection steps on ln(B / A): 80 halve [ln 1e-150, 0] to below 3e-22.
constexpr int kBisectionSteps = 80;

/// Below this B / A the complete integrals come from their expansions in it:
/// std's modulus e = sqrt(1 - (B/A)^2) would round (B/A)^2 away (the terms
/// left out are below 1e-17 here).
constexpr double kSeriesBelow = 1e-3;

struct CompleteIntegrals {
  double K = 0.0, E = 0.0;
};

/// K(e) and E(e) of the modulus e = sqrt(1 - k^2), given the complementary
/// modulus k; for small k the expansions about k = 0 with L = ln(4 / k):
/// K = L + (L - 1) k^2 / 4 + 9 (L - 7/6) k^4 / 64 and
/// E = 1 + (L - 1/2) k^2 / 2 + 3 (L - 13/12) k^4 / 16
/// (Byrd & Friedman, Handbook of Elliptic Integrals, 900.05 and 900.07).
CompleteIntegrals complete_integrals(double k) {
  if (k >= kSeriesBelow) {
    const double e = std::sqrt(1.0 - k * k);
    return {std::comp_ellint_1(e), std::comp_ellint_2(e)};
  }
  const double L = std::log(4.0 / k), k2 = k * k, k4 = k2 * k2;
  return {L + 0.25 * (L - 1.0) * k2 + 9.0 / 64.0 * (L - 7.0 / 6.0) * k4,
          1.0 + 0.5 * (L - 0.5) * k2 + 3.0 / 16.0 * (L - 13.0 / 12.0) * k4};
}

/// The gap coefficient across the major axis over that along it, for the
/// axis ratio k = B / A: (E / k^2 - K) / (K - E), which falls from infinity
/// at k -> 0 to 1 at k = 1.
double coefficient_ratio(double k) {
  const auto [K, E] = complete_integrals(k);
  return (E / (k * k) - K) / (K - E);
}

}  // namespace

// Hertz theory of elliptic contacts (e.g. Johnson, Contact Mechanics, 3.5):
// with the major semi-axis A, the minor B and e^2 = 1 - B^2/A^2, the gap
// coefficient across the major axis over that along it is
// (E(e)/(1 - e^2) - K(e)) / (K(e) - E(e)).  The load and the coefficient
// along the major axis, here c_major = (2/pi^2) pi p0 B (K - E)/(e^2 A^2),
// give A^3 = 2 (K - E)/(pi e^2 c_major) with p0 A B = 1.
EllipticHertzContact dry_elliptic_hertz(double D) {
  if (std::abs(D - 1.0) < kCircularWithin) return {1.0, 1.0, 1.0};
  const double ratio = std::max(D, 1.0 / D);
  double lo = std::log(kSmallestAxisRatio), hi = 0.0;  // the ratio falls with ln(B / A)
  for (int step = 0; step < kBisectionSteps; ++step) {
    const double mid = 0.5 * (lo + hi);
    (coefficient_ratio(std::exp(mid)) > ratio ? lo : hi) = mid;
  }
  const double k = std::exp(0.5 * (lo + hi)), e2 = (1.0 - k) * (1.0 + k);
  const auto [K, E] = complete_integrals(k);
  const double c_major = 0.5 * std::min(1.0, D);
  const double major = std::cbrt(2.0 * (K - E) / (std::numbers::pi * e2 * c_major));
  const double minor = major * k;
  EllipticHertzContact hz;
  hz.ax = D >= 1.0 ? major : minor;
  hz.ay = D >= 1.0 ? minor : major;
  hz.p0 = 1.0 / (hz.ax * hz.ay);
  return hz;
}

}  // namespace ehlsim
