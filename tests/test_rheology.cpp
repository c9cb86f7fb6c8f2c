// Pointwise viscosity and density laws (model.md, "Lubricant models").
#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

#include "reynolds/ReynoldsOperator.hpp"
#include "rheology/Lubricant.hpp"

using namespace ehlsim;

namespace {

// A mineral-oil-like case: eta0 = 0.04 Pa s, alpha = 2e-8 1/Pa, ph* = 0.5 GPa.
constexpr double kEta0 = 0.04;
constexpr double kAlpha = 2e-8;
constexpr double kPh = 0.5e9;

Lubricant roelands_oil() {
  Lubricant l;
  l.viscosity = ViscosityModel::Roelands;
  l.eta0_Pa_s = kEta0;
  l.roelands_z = Lubricant::roelands_z_from_alpha(kAlpha, kEta0);
  l.ph_star_Pa = kPh;
  return l;
}

Lubricant barus(double alpha_bar) {
  Lubricant l;
  l.alpha_bar = alpha_bar;
  return l;
}

// d ln(eta_bar)/dP at P = 0, one-sided second-order difference (P < 0 is
// clamped, so a central difference would not see the law).
double log_slope_at_zero(const Lubricant& l, double dP) {
  const auto f = [&](double P) { return std::log(l.eta_bar(P)); };
  return (-3.0 * f(0.0) + 4.0 * f(dP) - f(2.0 * dP)) / (2.0 * dP);
}

}  // namespace

TEST(Rheology, BarusIsExponential) {
  const double alpha_bar = 16.91274;  // M = 100, L = 10 (model.md table)
  const Lubricant l = barus(alpha_bar);
  EXPECT_EQ(l.eta_bar(0.0), 1.0);
  for (const double P : {0.1, 0.5, 1.0, 1.7}) {
    // Same expression up to rounding: a few ulps.
    EXPECT_NEAR(l.eta_bar(P) / std::exp(alpha_bar * P), 1.0, 1e-14) << "P = " << P;
  }
  // Multiplicative in P: eta(P1 + P2) = eta(P1) eta(P2).
  EXPECT_NEAR(l.eta_bar(1.2) / (l.eta_bar(0.5) * l.eta_bar(0.7)), 1.0, 1e-13);
  EXPECT_EQ(l.rho_bar(1.0), 1.0);  // incompressible by default
}

TEST(Rheology, NegativePressureCountsAsZero) {
  Lubricant l = roelands_oil();
  l.density = DensityModel::DowsonHigginson;
  EXPECT_EQ(l.eta_bar(-0.3), 1.0);
  EXPECT_EQ(l.rho_bar(-0.3), 1.0);
  EXPECT_EQ(barus(10.0).eta_bar(-2.0), 1.0);
}

TEST(Rheology, RoelandsZFromAlpha) {
  // z = alpha p0 / (ln eta0 + 9.67) = 2e-8 * 1.96e8 / (ln 0.04 + 9.67) = 0.60765...
  const double z = Lubricant::roelands_z_from_alpha(kAlpha, kEta0);
  EXPECT_NEAR(z, 3.92 / (std::log(0.04) + 9.67), 1e-15);
  EXPECT_GT(z, 0.6);
  EXPECT_LT(z, 0.61);
  // eta0 at or below eta_inf = 6.31e-5 Pa s has no Roelands law.
  EXPECT_THROW((void)Lubricant::roelands_z_from_alpha(kAlpha, 5e-5), std::invalid_argument);
}

TEST(Rheology, RoelandsHasBarusSlopeAtZero) {
  const Lubricant l = roelands_oil();
  EXPECT_EQ(l.eta_bar(0.0), 1.0);
  // d ln(eta_bar)/dP|0 = alpha ph* = 10 by the choice of z.  Truncation of
  // the difference: dP^2 f'''/3, f''' = 6.45 z(z-1)(z-2)(ph*/p0)^3 ~ 36, i.e.
  // ~1e-7 absolute, 1e-8 relative; rounding ~ eps/dP ~ 1e-12.
  const double expected = kAlpha * kPh;
  EXPECT_NEAR(log_slope_at_zero(l, 1e-4) / expected, 1.0, 1e-6);
}

TEST(Rheology, RoelandsKeepsItsSlopeWhenPOverP0IsTiny) {
  // ph* = 1e-8 Pa with the z of alpha_bar = 10 (z ~ 4.6e16): p/p0 ~ 5e-17,
  // and 1 + p/p0 rounds to 1.  The law must still have the slope alpha ph*
  // = 10 at P = 0 and tend to lnterm (exp(10 P / lnterm) - 1): it was 0, an
  // isoviscous film.
  Lubricant l = roelands_oil();
  l.ph_star_Pa = 1e-8;
  l.roelands_z = Lubricant::roelands_z_from_alpha(10.0 / l.ph_star_Pa, kEta0);
  const double lnterm = std::log(kEta0) + kRoelandsLnEtaInf;
  EXPECT_NEAR(log_slope_at_zero(l, 1e-4) / 10.0, 1.0, 1e-6);
  EXPECT_NEAR(l.log_eta_bar(1.0) / (lnterm * std::expm1(10.0 / lnterm)), 1.0, 1e-9);
}

TEST(Rheology, RoelandsBelowBarusAtHighPressure) {
  // z < 1 makes ln(eta) concave in p, so Roelands lies below the Barus law of
  // the same initial slope; at 1 GPa the gap is large (orders of magnitude).
  const Lubricant r = roelands_oil();
  const Lubricant b = barus(kAlpha * kPh);
  for (const double P : {0.5, 1.0, 2.0}) EXPECT_LT(r.eta_bar(P), b.eta_bar(P)) << "P = " << P;
  EXPECT_LT(r.eta_bar(2.0), 1e-2 * b.eta_bar(2.0));
}

TEST(Rheology, RoelandsDoublingPoint) {
  // Where (1 + p/p0)^z = 2 the exponent equals ln eta0 + 9.67 exactly:
  // eta = eta0^2 / eta_inf, eta_inf = exp(-9.67) Pa s.
  const Lubricant l = roelands_oil();
  const double p = kRoelandsP0_Pa * (std::pow(2.0, 1.0 / l.roelands_z) - 1.0);
  EXPECT_NEAR(l.eta_bar(p / kPh) / (kEta0 * std::exp(kRoelandsLnEtaInf)), 1.0, 1e-12);
}

TEST(Rheology, DowsonHigginsonLimits) {
  Lubricant l;
  l.density = DensityModel::DowsonHigginson;
  l.ph_star_Pa = kPh;
  EXPECT_EQ(l.rho_bar(0.0), 1.0);
  // p = 0.59 GPa: (A + 1.34 A)/(2 A) = 1.17, halfway to the limit.
  EXPECT_NEAR(l.rho_bar(kDowsonHigginsonA_Pa / kPh), 1.17, 1e-14);
  // p -> infinity: 1.34 - 0.34 A/p; at p = 5e14 Pa the gap is 4e-7.
  EXPECT_NEAR(l.rho_bar(1e6), 1.34, 1e-6);
  EXPECT_LT(l.rho_bar(1e6), 1.34);
}

TEST(Rheology, MonotoneInPressure) {
  Lubricant dh = roelands_oil();
  dh.density = DensityModel::DowsonHigginson;
  const Lubricant b = barus(16.91274);
  double eta_r = 1.0, eta_b = 1.0, rho = 1.0;
  for (int k = 1; k <= 100; ++k) {
    const double P = 0.05 * k;  // up to 5 ph*: beyond any pressure spike seen in the paper
    EXPECT_GT(dh.eta_bar(P), eta_r);
    EXPECT_GT(b.eta_bar(P), eta_b);
    EXPECT_GT(dh.rho_bar(P), rho);
    EXPECT_LT(dh.rho_bar(P), kDowsonHigginsonB);
    eta_r = dh.eta_bar(P);
    eta_b = b.eta_bar(P);
    rho = dh.rho_bar(P);
  }
}

TEST(Rheology, ValidateRejectsMissingParameters) {
  EXPECT_NO_THROW(roelands_oil().validate());
  EXPECT_NO_THROW(barus(10.0).validate());
  Lubricant l = roelands_oil();
  l.eta0_Pa_s = 0.0;
  EXPECT_THROW(l.validate(), std::invalid_argument);
  l = roelands_oil();
  l.ph_star_Pa = 0.0;
  EXPECT_THROW(l.validate(), std::invalid_argument);
  Lubricant dh;
  dh.density = DensityModel::DowsonHigginson;
  EXPECT_THROW(dh.validate(), std::invalid_argument);
}

// The logarithmic face mean is the exact flux of the Kirchhoff transform for
// Barus at constant film: with xi(P) = exp(-alpha P), the 1-D flux between two
// points is (Phi(P1) - Phi(P2)) / h, Phi(P) = Int_0^P xi = (1 - exp(-alpha P)) / alpha,
// so mean(xi1, xi2) (P2 - P1) must equal Phi(P2) - Phi(P1) for every jump.
TEST(FaceMean, LogarithmicMeanIsTheExactBarusFlux) {
  using ehlsim::FaceMean;
  using ehlsim::reynolds::face_coefficient;
  constexpr double alpha = 16.91274;  // model.md, M = 100, L = 10
  const auto xi = [&](double P) { return std::exp(-alpha * P); };
  for (double P1 : {0.0, 0.3, 1.0}) {
    for (double jump : {1e-7, 1e-3, 0.05, 0.5, 2.5}) {
      const double P2 = P1 + jump;
      // Phi(P2) - Phi(P1) without cancellation.
      const double exact = -xi(P1) * std::expm1(-alpha * jump) / alpha;
      const double log_flux = face_coefficient(xi(P1), xi(P2), FaceMean::Logarithmic) * jump;
      EXPECT_NEAR(log_flux / exact, 1.0, 1e-9) << "P1 = " << P1 << ", jump " << jump;
      if (alpha * jump > 5.0) {
        // Across an unresolved jump the arithmetic mean overestimates the flux
        // and the harmonic one underestimates it, both by large factors.
        EXPECT_GT(face_coefficient(xi(P1), xi(P2), FaceMean::Arithmetic) * jump, 2.0 * exact);
        EXPECT_LT(face_coefficient(xi(P1), xi(P2), FaceMean::Harmonic) * jump, 0.5 * exact);
      }
    }
  }
}
