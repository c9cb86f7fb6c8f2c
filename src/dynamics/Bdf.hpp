#pragma once
// Backward differentiation formulas for the squeeze term d(rho H)/dT of the
// Reynolds equation (model.md): d/dT u ~ (b0 u^{n+1} + b1 u^n + b2 u^{n-1}) / dT.

namespace ehlsim {

struct BdfCoefficients {
  double b0, b1, b2;
};

/// BDF1 (implicit Euler): starts the time integration, which has one level only.
inline constexpr BdfCoefficients kBdf1{1.0, -1.0, 0.0};

/// BDF2 for a step dT after a step dT / omega (variable-step BDF2, e.g.
/// Hairer, Norsett & Wanner, Solving Ordinary Differential Equations I,
/// section III.5): exact for quadratics in T.  omega = 1 gives (3/2, -2, 1/2)
/// exactly, the constant-step formula.
[[nodiscard]] constexpr BdfCoefficients bdf2(double omega) {
  return {(1.0 + 2.0 * omega) / (1.0 + omega), -(1.0 + omega), omega * omega / (1.0 + omega)};
}

}  // namespace ehlsim
