#include "impact/Scaling.hpp"

#include <cmath>
#include <numbers>

namespace ehlsim {

namespace {
constexpr double kPi = std::numbers::pi;
// M^4 lambda_bar^3 = 128 pi^3 / 3
constexpr double kMoesLambdaConstant = 128.0 * kPi * kPi * kPi / 3.0;
}  // namespace

double moes_lambda_bar(double M) { return std::cbrt(kMoesLambdaConstant / std::pow(M, 4)); }

double moes_alpha_bar(double M, double L) { return (L / kPi) * std::cbrt(1.5 * M); }

double moes_M(double lambda_bar) {
  return std::pow(kMoesLambdaConstant / (lambda_bar * lambda_bar * lambda_bar), 0.25);
}

double moes_L(double lambda_bar, double alpha_bar) {
  return kPi * alpha_bar * std::pow(lambda_bar / (6.0 * kPi), 0.25);
}

double reduced_modulus(double E1, double nu1, double E2, double nu2) {
  return 2.0 / ((1.0 - nu1 * nu1) / E1 + (1.0 - nu2 * nu2) / E2);
}

double sphere_mass(double radius_m, double density_kg_m3) {
  return density_kg_m3 * 4.0 / 3.0 * kPi * radius_m * radius_m * radius_m;
}

PhysicalCase with_reference_scales(PhysicalCase c) {
  const double R = c.reduced_radius_m;
  const double v0 = c.impact_speed_m_s;
  const double E = c.reduced_modulus_Pa;
  c.delta_star_m = std::pow(3.0 * c.mass_kg * v0 * v0 / (2.0 * E * std::sqrt(R)), 0.4);
  c.a_star_m = std::sqrt(R * c.delta_star_m);
  c.ph_star_Pa = E * c.a_star_m / (kPi * R);
  c.F_star_N = 2.0 * kPi / 3.0 * c.ph_star_Pa * c.a_star_m * c.a_star_m;
  c.t_bar_s = c.delta_star_m / v0;
  return c;
}

MoesGroups moes_groups(const PhysicalCase& c) {
  MoesGroups g;
  const double R = c.reduced_radius_m;
  g.lambda_bar = 12.0 * c.eta0_Pa_s * R * R / (c.a_star_m * c.a_star_m * c.t_bar_s * c.ph_star_Pa);
  g.alpha_bar = c.alpha_per_Pa * c.ph_star_Pa;
  g.M = moes_M(g.lambda_bar);
  g.L = moes_L(g.lambda_bar, g.alpha_bar);
  return g;
}

}  // namespace ehlsim
