#pragma once
// Moes parameters and the reference scales of the dry Hertz impact (model.md,
// "Reference scales" and "Moes parameters").
//
//   lambda_bar = (128 pi^3 / (3 M^4))^(1/3)       M = (128 pi^3 / (3 lambda_bar^3))^(1/4)
//   alpha_bar  = (L / pi) (3 M / 2)^(1/3)         L = pi alpha_bar (lambda_bar / (6 pi))^(1/4)
//
// Physical scales from the ball radius R, mass m, approach speed v0, reduced
// modulus E' (2/E' = (1 - nu1^2)/E1 + (1 - nu2^2)/E2), eta0 and alpha:
//
//   delta* = (3 m v0^2 / (2 E' sqrt(R)))^(2/5)    a* = sqrt(R delta*)
//   ph*    = E' a* / (pi R)                      F* = (2 pi / 3) ph* a*^2
//   t_bar  = delta* / v0
//   lambda_bar = 12 eta0 R^2 / (a*^2 t_bar ph*) = 8 pi eta0 R^2 / (m v0)
//   alpha_bar  = alpha ph*
#include "impact/ImpactConfig.hpp"

namespace ehlsim {

/// lambda_bar from the Moes load parameter M (M > 0).
[[nodiscard]] double moes_lambda_bar(double M);
/// alpha_bar from the Moes parameters M (> 0) and L (>= 0).
[[nodiscard]] double moes_alpha_bar(double M, double L);
/// The Moes load parameter M from lambda_bar (> 0).
[[nodiscard]] double moes_M(double lambda_bar);
/// The Moes lubricant parameter L from lambda_bar (> 0) and alpha_bar (>= 0).
[[nodiscard]] double moes_L(double lambda_bar, double alpha_bar);

/// Reduced modulus E' [Pa]: 2/E' = (1 - nu1^2)/E1 + (1 - nu2^2)/E2.
[[nodiscard]] double reduced_modulus(double E1, double nu1, double E2, double nu2);

/// Mass [kg] of a solid sphere of radius R [m] and density rho [kg/m^3].
[[nodiscard]] double sphere_mass(double radius_m, double density_kg_m3);

/// Fills the derived scales (delta*, a*, ph*, F*, t_bar) of a PhysicalCase from
/// its inputs (R, m, v0, E' must be > 0).  Returns the completed case.
[[nodiscard]] PhysicalCase with_reference_scales(PhysicalCase inputs);

/// The four dimensionless groups of one case.
struct MoesGroups {
  double M = 0.0;
  double L = 0.0;
  double lambda_bar = 0.0;
  double alpha_bar = 0.0;
};

/// lambda_bar, alpha_bar and M, L of a physical case whose scales are filled in.
[[nodiscard]] MoesGroups moes_groups(const PhysicalCase& physical);

}  // namespace ehlsim
