// Ball dynamics: the Newmark scheme and the dry Hertz impact (model.md,
// "Reference values" and "Analytic checks").
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <vector>

#include "dynamics/Bdf.hpp"
#include "dynamics/DryHertz.hpp"
#include "dynamics/Newmark.hpp"

using namespace ehlsim;

namespace {

// Exact dry impact for Delta0 = 1, V0 = 1.  In contact d2D/dT2 = (-D)^(3/2),
// so V^2/2 + (2/5)(-D)^(5/2) = 1/2: the maximum approach is
// D_m = (5/4)^(2/5), and with x = D_m u^(2/5) the contact time is
//   T_c = 2 Int_0^{D_m} dx / sqrt(1 - (4/5) x^(5/2)) = 2 D_m (2/5) B(2/5, 1/2)
// (Johnson: 2.9432 D_m).  Contact starts at T = 1 (uniform approach from 1).
const double kDeltaMin = -std::pow(1.25, 0.4);
const double kContactTime =
    2.0 * std::pow(1.25, 0.4) * 0.4 * std::tgamma(0.4) * std::tgamma(0.5) / std::tgamma(0.9);
constexpr double kContactStart = 1.0;

// Delta at time T by linear interpolation of the recorded trajectory.
double delta_at(const DryImpact& r, double T) {
  for (std::size_t k = 0; k + 1 < r.T.size(); ++k)
    if (r.T[k] <= T && T <= r.T[k + 1]) {
      const double w = (T - r.T[k]) / (r.T[k + 1] - r.T[k]);
      return (1.0 - w) * r.Delta[k] + w * r.Delta[k + 1];
    }
  return std::nan("");
}

}  // namespace

// ---------------------------------------------------------------- Newmark

TEST(Newmark, ExactForConstantForce) {
  // Average acceleration integrates a constant acceleration exactly:
  // Delta = D0 + V0 T + a T^2/2.
  const double dT = 0.1, force = 0.7;
  const double a = kForceToAcceleration * force;
  const Newmark scheme(dT);
  BallState s{0.0, 1.0, -1.0, a};
  for (int k = 0; k < 25; ++k) s = scheme.advance(s, force);
  const double T = 25 * dT;
  EXPECT_NEAR(s.T, T, 1e-13);
  EXPECT_NEAR(s.Delta, 1.0 - T + 0.5 * a * T * T, 1e-13);
  EXPECT_NEAR(s.V, -1.0 + a * T, 1e-13);
  EXPECT_EQ(s.A, a);
}

TEST(Newmark, DeltaIsLinearInTheNewForce) {
  const Newmark scheme(0.02);
  const BallState s{1.0, -0.3, 0.4, 0.9};
  const double f0 = scheme.delta_for_force(s, 1.0), f1 = scheme.delta_for_force(s, 3.0);
  EXPECT_NEAR((f1 - f0) / 2.0, scheme.d_delta_d_force(), 1e-15);
  EXPECT_NEAR(scheme.d_delta_d_force(), 0.25 * 0.02 * 0.02 * 3.0 / (2.0 * std::numbers::pi), 1e-18);
  EXPECT_EQ(scheme.advance(s, 3.0).Delta, f1);
  EXPECT_THROW(Newmark(0.0), std::invalid_argument);
  EXPECT_THROW(Newmark(-1e-3), std::invalid_argument);
}

TEST(Newmark, ConservesEnergyOfLinearSpring) {
  // For a linear spring (a = -w^2 Delta) beta = 1/4, gamma = 1/2 conserves
  // V^2/2 + w^2 Delta^2/2 exactly (no numerical damping), whatever dT; only
  // rounding remains after 1000 steps of w dT = 0.5.
  const double w2 = 4.0, dT = 0.25;
  const double stiffness = w2 / kForceToAcceleration;  // force = -stiffness Delta
  const Newmark scheme(dT);
  BallState s{0.0, 1.0, -1.0, -w2 * 1.0};
  const auto energy = [w2](const BallState& b) {
    return 0.5 * b.V * b.V + 0.5 * w2 * b.Delta * b.Delta;
  };
  const double e0 = energy(s);
  for (int k = 0; k < 1000; ++k) {
    // Delta_new = base + c (-stiffness Delta_new), solved in closed form.
    const double base = scheme.delta_for_force(s, 0.0);
    const double delta_new = base / (1.0 + scheme.d_delta_d_force() * stiffness);
    s = scheme.advance(s, -stiffness * delta_new);
  }
  EXPECT_NEAR(energy(s) / e0, 1.0, 1e-12);
}

// ---------------------------------------------------------------- dry Hertz

TEST(DryHertz, ForceAndContactRadius) {
  EXPECT_NEAR(dry_hertz_force(-1.0), 2.0 * std::numbers::pi / 3.0, 1e-15);
  EXPECT_NEAR(kForceToAcceleration * dry_hertz_force(-0.49), std::pow(0.49, 1.5), 1e-15);
  EXPECT_EQ(dry_hertz_force(0.0), 0.0);
  EXPECT_EQ(dry_hertz_force(0.2), 0.0);
  EXPECT_NEAR(dry_contact_radius(-0.49), 0.7, 1e-15);
  EXPECT_EQ(dry_contact_radius(0.3), 0.0);
}

TEST(DryHertz, ReferenceImpact) {
  // dT = 1e-3: the O(dT^2) errors are below 3.2e-7 (measured; constants
  // <= 0.32, see SecondOrderInTimeStep), so 1e-6 against the exact values.
  const DryImpact r = simulate_dry_hertz(1.0, 1.0, 1e-3, 10.0);
  const double tol = 1e-6;
  EXPECT_NEAR(r.T_contact, kContactStart, tol);
  EXPECT_NEAR(r.T_lift_off - r.T_contact, kContactTime, tol);
  EXPECT_NEAR(r.Delta_min, kDeltaMin, tol);
  EXPECT_NEAR(r.T_Delta_min, kContactStart + 0.5 * kContactTime, tol);  // symmetric impact
  EXPECT_NEAR(r.rebound_speed, 1.0, tol);                               // no loss
  EXPECT_NEAR(r.impulse, 2.0, tol);
  // Trapezoidal impulse = change of V exactly (gamma = 1/2), up to rounding.
  EXPECT_NEAR(r.impulse, r.rebound_speed + 1.0, 1e-12);
  // The digits quoted in model.md, at their rounding.
  EXPECT_NEAR(r.T_contact, 1.0000, 5e-5);
  EXPECT_NEAR(r.T_lift_off, 4.2181, 5e-5);
  EXPECT_NEAR(r.T_lift_off - r.T_contact, 3.2181, 5e-5);
  EXPECT_NEAR(r.Delta_min, -1.09336, 5e-6);
  EXPECT_NEAR(r.T_Delta_min, 2.6090, 5e-5);
  // Trajectory ends at the first step after lift-off.
  EXPECT_GE(r.Delta.back(), 0.0);
  EXPECT_LT(r.T.back() - r.T_lift_off, 1e-3);
}

TEST(DryHertz, ContactRadiusHistory) {
  // model.md, A(T) = sqrt(-Delta(T)) to 4 digits.  Linear interpolation of
  // the dT = 1e-3 trajectory adds < 2e-7 to Delta, i.e. < 1e-6 to A >= 0.13.
  const DryImpact r = simulate_dry_hertz(1.0, 1.0, 1e-3, 10.0);
  const std::vector<std::pair<double, double>> reference = {{1.5, 0.7000},   {2.609, 1.0456},
                                                            {3.223, 0.9424}, {3.574, 0.7874},
                                                            {4.0, 0.4664},   {4.2, 0.1344}};
  for (const auto& [T, A] : reference)
    EXPECT_NEAR(dry_contact_radius(delta_at(r, T)), A, 5e-5 + 1e-6) << "T = " << T;
}

TEST(DryHertz, SecondOrderInTimeStep) {
  // dT = 0.0123 * 2^-k does not divide 1, so contact starts and ends inside
  // steps and the crossing interpolation is exercised.  Measured orders of
  // Delta_min: 1.96, 2.03, 1.99; of T_lift_off: 2.01, 2.00, 2.01.
  std::vector<double> e_min, e_lift;
  for (const double dT : {0.0246, 0.0123, 0.00615, 0.003075}) {
    const DryImpact r = simulate_dry_hertz(1.0, 1.0, dT, 10.0);
    e_min.push_back(std::fabs(r.Delta_min - kDeltaMin));
    e_lift.push_back(std::fabs(r.T_lift_off - (kContactStart + kContactTime)));
    // Contact onset: uniform motion before it, the force grows like
    // (T - T0)^(3/2) after it, so the linear crossing is O(dT^(7/2)).
    EXPECT_NEAR(r.T_contact, kContactStart, std::pow(dT, 3.5)) << "dT = " << dT;
    // Time-symmetric scheme, symmetric impact: the rebound speed error is
    // O(dT^2) with a small, sign-changing constant (measured |c| < 8e-3).
    EXPECT_NEAR(r.rebound_speed, 1.0, 0.05 * dT * dT) << "dT = " << dT;
  }
  for (std::size_t k = 0; k + 1 < e_min.size(); ++k) {
    const double p_min = std::log2(e_min[k] / e_min[k + 1]);
    const double p_lift = std::log2(e_lift[k] / e_lift[k + 1]);
    EXPECT_GE(p_min, 1.7);
    EXPECT_LE(p_min, 2.3);
    EXPECT_GE(p_lift, 1.7);
    EXPECT_LE(p_lift, 2.3);
  }
}

TEST(DryHertz, NoContactWhenMovingAway) {
  const DryImpact r = simulate_dry_hertz(1.0, -1.0, 0.01, 2.0);  // V0 < 0: receding
  EXPECT_TRUE(std::isnan(r.T_contact));
  EXPECT_TRUE(std::isnan(r.T_lift_off));
  EXPECT_TRUE(std::isnan(r.Delta_min));
  EXPECT_NEAR(r.T.back(), 2.0, 1e-12);
  EXPECT_NEAR(r.Delta.back(), 3.0, 1e-12);
  EXPECT_EQ(r.impulse, 0.0);
  EXPECT_THROW((void)simulate_dry_hertz(1.0, 1.0, 0.01, std::numeric_limits<double>::infinity()),
               std::invalid_argument);
}

// ---------------------------------------------------------------------------
// Variable-step BDF2 (dynamics/Bdf.hpp), used where a time step is solved in halves.

TEST(Bdf2, IsExactForQuadraticsAtAnyStepRatio) {
  // u = 1 + 2 T - 3 T^2: u'(T) = 2 - 6 T.  Levels T0 - dT/omega, T0, T0 + dT.
  const auto u = [](double T) { return 1.0 + 2.0 * T - 3.0 * T * T; };
  const double T0 = 0.7, dT = 0.01;
  for (const double omega : {0.25, 0.5, 1.0, 2.0}) {
    const BdfCoefficients b = bdf2(omega);
    const double derivative = (b.b0 * u(T0 + dT) + b.b1 * u(T0) + b.b2 * u(T0 - dT / omega)) / dT;
    EXPECT_NEAR(derivative, 2.0 - 6.0 * (T0 + dT), 1e-9) << "omega = " << omega;
  }
}

TEST(Bdf2, ConstantStepGivesTheClassicalCoefficientsExactly) {
  const BdfCoefficients b = bdf2(1.0);
  EXPECT_EQ(b.b0, 1.5);
  EXPECT_EQ(b.b1, -2.0);
  EXPECT_EQ(b.b2, 0.5);
}

TEST(Bdf2, ErrorIsSecondOrderInTheStep) {
  // u = exp(T) with steps dT after dT / 2: the error of u'(T0 + dT) falls 4
  // times when dT halves.
  const double T0 = 0.3;
  const auto error = [&](double dT) {
    const BdfCoefficients b = bdf2(2.0);
    const double derivative =
        (b.b0 * std::exp(T0 + dT) + b.b1 * std::exp(T0) + b.b2 * std::exp(T0 - dT / 2.0)) / dT;
    return std::fabs(derivative - std::exp(T0 + dT));
  };
  const double order = std::log2(error(0.02) / error(0.01));
  EXPECT_NEAR(order, 2.0, 0.05);
}
