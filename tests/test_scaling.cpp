// Moes parameters and physical reference scales (model.md).
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "impact/Scaling.hpp"
#include "support/SteelBall.hpp"

namespace ehlsim {
namespace {

constexpr double kPi = std::numbers::pi;

struct MoesRow {
  double M, L, lambda_bar, alpha_bar;
};

// model.md, "Moes parameters" (6 significant digits).
constexpr MoesRow kTable[] = {
    {10, 10, 0.509541, 7.85020},   {20, 10, 0.202212, 9.89063},    {50, 10, 0.059596, 13.42365},
    {100, 10, 0.023651, 16.91274}, {1000, 10, 0.001098, 36.43739},
};

double relative(double a, double b) { return std::abs(a - b) / std::abs(b); }

TEST(Scaling, MoesTableOfModelMd) {
  for (const auto& row : kTable) {
    SCOPED_TRACE(row.M);
    // The table's lambda_bar has 6 decimals (fewer significant digits for large M).
    EXPECT_NEAR(moes_lambda_bar(row.M), row.lambda_bar, 0.5e-6);
    EXPECT_NEAR(moes_alpha_bar(row.M, row.L), row.alpha_bar, 0.5e-5);
  }
}

TEST(Scaling, MoesRoundTrip) {
  for (const double M : {0.5, 10.0, 20.0, 50.0, 100.0, 1000.0, 1e5}) {
    for (const double L : {0.0, 1.0, 10.0, 25.0}) {
      const double lambda_bar = moes_lambda_bar(M);
      const double alpha_bar = moes_alpha_bar(M, L);
      EXPECT_LT(relative(moes_M(lambda_bar), M), 1e-13);
      EXPECT_NEAR(moes_L(lambda_bar, alpha_bar), L, 1e-13 * std::max(1.0, L));
    }
  }
}

TEST(Scaling, ReducedModulusAndSphereMass) {
  // Steel on steel: E' = E / (1 - nu^2).
  EXPECT_LT(relative(reduced_modulus(210e9, 0.3, 210e9, 0.3), 210e9 / 0.91), 1e-15);
  // A rigid flat: 2/E' = (1 - nu1^2)/E1.
  EXPECT_LT(relative(reduced_modulus(100e9, 0.0, 1e300, 0.0), 200e9), 1e-12);
  EXPECT_LT(relative(sphere_mass(0.01, 7850.0), 7850.0 * 4.0 / 3.0 * kPi * 1e-6), 1e-15);
}

using ehlsim::testing::steel_ball;

TEST(Scaling, ReferenceScalesDefinitions) {
  const PhysicalCase p = steel_ball();
  const double R = p.reduced_radius_m;
  const double m = p.mass_kg;
  const double v0 = p.impact_speed_m_s;
  const double E = p.reduced_modulus_Pa;
  EXPECT_LT(relative(std::pow(p.delta_star_m, 2.5), 3 * m * v0 * v0 / (2 * E * std::sqrt(R))),
            1e-13);
  EXPECT_LT(relative(p.a_star_m * p.a_star_m, R * p.delta_star_m), 1e-14);
  EXPECT_LT(relative(p.ph_star_Pa, E * p.a_star_m / (kPi * R)), 1e-14);
  EXPECT_LT(relative(p.t_bar_s, p.delta_star_m / v0), 1e-14);
  // The scaling makes the dynamics constant 3 / (2 pi): m v0^2 = F* delta*.
  EXPECT_LT(relative(m * v0 * v0, p.F_star_N * p.delta_star_m), 1e-13);
}

TEST(Scaling, LambdaBarIsEightPiEta0RSquaredOverMomentum) {
  for (const double v0 : {0.01, 0.1, 1.0, 10.0}) {
    PhysicalCase p = steel_ball();
    p.impact_speed_m_s = v0;
    p = with_reference_scales(p);
    const MoesGroups g = moes_groups(p);
    const double R = p.reduced_radius_m;
    EXPECT_LT(relative(g.lambda_bar, 8 * kPi * p.eta0_Pa_s * R * R / (p.mass_kg * v0)), 1e-12);
    // Impact Stokes number: lambda_bar = 4 / (3 St), St = m v0 / (6 pi eta0 R^2).
    const double St = p.mass_kg * v0 / (6 * kPi * p.eta0_Pa_s * R * R);
    EXPECT_LT(relative(g.lambda_bar, 4.0 / (3.0 * St)), 1e-12);
    // alpha_bar = alpha ph* = (alpha E' / pi) sqrt(delta* / R).
    EXPECT_LT(relative(g.alpha_bar,
                       p.alpha_per_Pa * p.reduced_modulus_Pa / kPi * std::sqrt(p.delta_star_m / R)),
              1e-13);
    // M, L consistent with lambda_bar, alpha_bar.
    EXPECT_LT(relative(moes_lambda_bar(g.M), g.lambda_bar), 1e-13);
    EXPECT_LT(relative(moes_alpha_bar(g.M, g.L), g.alpha_bar), 1e-13);
  }
}

TEST(Scaling, SteelBallExampleValues) {
  // examples/physical.toml: R = 10 mm steel ball on steel, v0 = 0.1 m/s,
  // eta0 = 0.04 Pa s, alpha = 2e-8 1/Pa.
  const PhysicalCase p = steel_ball();
  const MoesGroups g = moes_groups(p);
  EXPECT_NEAR(p.ph_star_Pa / 1e9, 1.355, 0.0005);
  EXPECT_NEAR(p.delta_star_m * 1e6, 3.404, 0.0005);
  EXPECT_NEAR(p.a_star_m * 1e3, 0.1845, 0.00005);
  EXPECT_NEAR(p.F_star_N, 96.6, 0.05);
  EXPECT_NEAR(p.t_bar_s * 1e6, 34.04, 0.005);
  EXPECT_NEAR(g.lambda_bar, 0.03057, 0.000005);
  EXPECT_NEAR(g.M, 82.49, 0.005);
  EXPECT_NEAR(g.L, 17.09, 0.005);
}

}  // namespace
}  // namespace ehlsim
