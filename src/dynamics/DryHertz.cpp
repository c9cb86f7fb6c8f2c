#include "dynamics/DryHertz.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <utility>

#include "dynamics/Newmark.hpp"

namespace ehlsim {
namespace {

/// Hertz force factor 2 pi / 3: Int Int P for P = A sqrt(1 - r^2/A^2) is
/// (2 pi / 3) A^3 and A^2 = -Delta (model.md).
constexpr double kHertzForceFactor = 2.0 * std::numbers::pi / 3.0;
/// Convergence of the implicit step, relative to max(1, |Delta|).
constexpr double kStepTolerance = 1e-14;
/// Newton converges in a handful of steps; bisection needs about 60 at worst.
constexpr int kMaxStepIterations = 200;
/// Bisection steps for the turning point of the Hermite cubic (2^-60 of a step).
constexpr int kTurningPointBisections = 60;

/// Solves D = base + c F(D) (the Newmark step with the Hertz force).
/// f(D) = D - base - c F(D) increases with slope 1 + c pi sqrt(-D) >= 1, so
/// the root is unique and lies in [base, max(base, 0)].
double solve_step(const Newmark& scheme, const BallState& s) {
  const double base = scheme.delta_for_force(s, 0.0);
  if (base >= 0.0) return base;  // no contact at the new level
  const double c = scheme.d_delta_d_force();
  double lo = base, hi = 0.0;  // f(lo) <= 0 < f(hi)
  double D = base;
  for (int it = 0; it < kMaxStepIterations; ++it) {
    const double f = D - base - c * dry_hertz_force(D);
    if (f == 0.0) return D;
    (f < 0.0 ? lo : hi) = D;
    // f'(D) = 1 + c (2 pi/3)(3/2) sqrt(-D): d(x^(3/2))/dx = (3/2) x^(1/2).
    const double slope = 1.0 + c * kHertzForceFactor * 1.5 * std::sqrt(std::max(-D, 0.0));
    double next = D - f / slope;
    if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);  // safeguard: stay in the bracket
    if (std::fabs(next - D) <= kStepTolerance * std::max(1.0, std::fabs(D))) return next;
    D = next;
  }
  throw std::runtime_error("simulate_dry_hertz: the implicit step did not converge");
}

/// Time where Delta crosses 0 within [a, b], linear interpolation.
double crossing_time(const BallState& a, const BallState& b) {
  return a.T + (b.T - a.T) * a.Delta / (a.Delta - b.Delta);
}

/// Minimum of the cubic Hermite interpolant of (Delta, V) on [a.T, b.T], given
/// a.V < 0 <= b.V.  Returns {T, Delta}.
std::pair<double, double> hermite_minimum(const BallState& a, const BallState& b) {
  const double h = b.T - a.T;
  const double d0 = a.Delta, d1 = b.Delta, m0 = h * a.V, m1 = h * b.V;
  const auto value = [&](double t) {
    const double t2 = t * t, t3 = t2 * t;
    return (2 * t3 - 3 * t2 + 1) * d0 + (t3 - 2 * t2 + t) * m0 + (-2 * t3 + 3 * t2) * d1 +
           (t3 - t2) * m1;
  };
  const auto slope = [&](double t) {
    const double t2 = t * t;
    return (6 * t2 - 6 * t) * d0 + (3 * t2 - 4 * t + 1) * m0 + (-6 * t2 + 6 * t) * d1 +
           (3 * t2 - 2 * t) * m1;
  };
  // slope(0) = m0 < 0 <= slope(1) = m1: bisection brackets the turning point.
  double lo = 0.0, hi = 1.0;
  for (int it = 0; it < kTurningPointBisections; ++it) {
    const double mid = 0.5 * (lo + hi);
    (slope(mid) < 0.0 ? lo : hi) = mid;
  }
  const double t = 0.5 * (lo + hi);
  return {a.T + t * h, value(t)};
}

/// The dry contact time scales as V0^(-1/5) (Hertz).
constexpr double kContactDurationExponent = -0.2;
/// The largest approach grows as the energy^(2/5) (Hertz).
constexpr double kApproachExponent = 0.4;
}  // namespace

double dry_contact_duration(double V0) {
  return kDryContactDuration * std::pow(V0, kContactDurationExponent);
}

double dry_largest_approach(double energy) { return std::pow(2.5 * energy, kApproachExponent); }

double dry_largest_contact_radius(double V0) {
  return std::sqrt(dry_largest_approach(0.5 * V0 * V0));
}

double dry_hertz_force(double Delta) {
  if (!(Delta < 0.0)) return 0.0;
  const double x = -Delta;
  return kHertzForceFactor * x * std::sqrt(x);
}

double dry_contact_radius(double Delta) { return std::sqrt(std::max(-Delta, 0.0)); }

DryImpact simulate_dry_hertz(double Delta0, double V0, double dT, double T_end_max) {
  const Newmark scheme(dT);
  if (!std::isfinite(T_end_max))
    throw std::invalid_argument("simulate_dry_hertz: T_end_max must be finite");

  DryImpact out;
  BallState s{0.0, Delta0, -V0, kForceToAcceleration * dry_hertz_force(Delta0)};
  const auto record = [&out](const BallState& state) {
    out.T.push_back(state.T);
    out.Delta.push_back(state.Delta);
    out.V.push_back(state.V);
  };
  record(s);
  bool had_contact = Delta0 < 0.0;
  if (had_contact) out.T_contact = 0.0;

  for (long step = 1; s.T < T_end_max; ++step) {
    BallState next = scheme.advance(s, dry_hertz_force(solve_step(scheme, s)));
    next.T = static_cast<double>(step) * dT;  // no round-off drift over many steps
    out.impulse += 0.5 * dT * (s.A + next.A);
    if (!had_contact && next.Delta < 0.0) {
      out.T_contact = crossing_time(s, next);
      had_contact = true;
    }
    if (std::isnan(out.Delta_min) && s.V < 0.0 && next.V >= 0.0) {
      const auto [T_min, D_min] = hermite_minimum(s, next);
      out.T_Delta_min = T_min;
      out.Delta_min = D_min;
    }
    record(next);
    if (had_contact && s.Delta < 0.0 && next.Delta >= 0.0) {
      out.T_lift_off = crossing_time(s, next);
      out.rebound_speed = next.V;  // A = 0 from here on: V stays
      break;
    }
    s = next;
  }
  return out;
}

}  // namespace ehlsim
