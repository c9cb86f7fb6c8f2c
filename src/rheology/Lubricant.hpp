#pragma once
// Pointwise dimensionless viscosity eta_bar = eta/eta0 and density
// rho_bar = rho/rho0 as functions of the dimensionless pressure P = p/ph*
// (model.md, "Lubricant models").
//
// eta_bar() and rho_bar() are called for every grid point in every relaxation
// sweep, so they are defined inline here.
#include <algorithm>
#include <cmath>

#include "rheology/Models.hpp"

namespace ehlsim {

/// Roelands (1966) reference pressure p0 [Pa] in
/// eta = eta0 exp{(ln eta0 + 9.67)[-1 + (1 + p/p0)^z]}.
inline constexpr double kRoelandsP0_Pa = 1.96e8;
/// Roelands (1966): 9.67 = -ln(eta_inf / (1 Pa s)), with eta_inf = 6.31e-5 Pa s
/// Roelands' universal asymptotic viscosity, i.e. the law is
/// ln(eta/eta_inf) = ln(eta0/eta_inf)(1 + p/p0)^z.
inline constexpr double kRoelandsLnEtaInf = 9.67;
/// Dowson & Higginson (1966): rho/rho0 = (A + B p)/(A + p), A [Pa] and B below.
inline constexpr double kDowsonHigginsonA_Pa = 0.59e9;
/// Dowson & Higginson (1966): the asymptotic density ratio for p -> infinity.
inline constexpr double kDowsonHigginsonB = 1.34;

struct Lubricant {
  ViscosityModel viscosity = ViscosityModel::Barus;
  DensityModel density = DensityModel::Incompressible;
  double alpha_bar = 0.0;   ///< Barus: alpha ph* (dimensionless)
  double eta0_Pa_s = 0.0;   ///< Roelands: ambient viscosity [Pa s]
  double roelands_z = 0.0;  ///< Roelands: pressure-viscosity index
  double ph_star_Pa = 0.0;  ///< Roelands and Dowson-Higginson: reference Hertz pressure [Pa]

  /// This lubricant with the case's alpha_bar: a run's configuration holds
  /// alpha_bar once, with M, L and lambda_bar ([case]), and a test or a sweep
  /// that changes it there changes the solver's law.
  [[nodiscard]] Lubricant with_alpha_bar(double case_alpha_bar) const {
    Lubricant lub = *this;
    lub.alpha_bar = case_alpha_bar;
    return lub;
  }

  /// eta/eta0 at dimensionless pressure P.  P < 0 (cavitated, should not be
  /// passed) counts as 0, so a slightly negative iterate cannot make eta < 1.
  [[nodiscard]] double eta_bar(double P) const { return std::exp(log_eta_bar(P)); }
  /// ln(eta/eta0): finite where eta_bar overflows (alpha_bar P > 709).
  [[nodiscard]] double log_eta_bar(double P) const {
    const double Pc = std::max(P, 0.0);
    if (viscosity == ViscosityModel::Barus) return alpha_bar * Pc;
    // (1 + x)^z - 1 as expm1(z log1p(x)): with pow, 1 + x rounded to 1 for
    // x below 1e-16, and a law of tiny p/p0 and huge z (ph* = 1e-8 Pa with
    // the z of L = 10) became isoviscous instead of its limit
    // (ln eta0 + 9.67) (exp(alpha p / (ln eta0 + 9.67)) - 1).
    return (std::log(eta0_Pa_s) + kRoelandsLnEtaInf) *
           std::expm1(roelands_z * std::log1p(Pc * ph_star_Pa / kRoelandsP0_Pa));
  }

  /// rho/rho0 at dimensionless pressure P (P < 0 counts as 0).
  [[nodiscard]] double rho_bar(double P) const {
    if (density == DensityModel::Incompressible) return 1.0;
    const double p = std::max(P, 0.0) * ph_star_Pa;
    return (kDowsonHigginsonA_Pa + kDowsonHigginsonB * p) / (kDowsonHigginsonA_Pa + p);
  }

  /// Roelands: the pressure-viscosity coefficient at p = 0 [1/Pa],
  /// d ln(eta)/dp|0 = z (ln eta0 + 9.67) / p0 (the inverse of
  /// roelands_z_from_alpha).
  [[nodiscard]] double roelands_alpha() const {
    return roelands_z * (std::log(eta0_Pa_s) + kRoelandsLnEtaInf) / kRoelandsP0_Pa;
  }

  /// Roelands index z that gives the pressure-viscosity coefficient alpha [1/Pa]
  /// at p = 0: d ln(eta)/dp|0 = z (ln eta0 + 9.67)/p0 = alpha.
  [[nodiscard]] static double roelands_z_from_alpha(double alpha_per_Pa, double eta0_Pa_s);

  /// Throws std::invalid_argument when a parameter the chosen models need is
  /// missing or out of range (e.g. Roelands without eta0 or ph*).
  void validate() const;
};

}  // namespace ehlsim
