#pragma once
// The central film thickness of a rolling elliptic EHL contact after
// Nijenbanning, Venner & Moes, "Film thickness in elastohydrodynamically
// lubricated elliptic contacts", Wear 176 (1994) 217-229, in Moes units
// (H_Moes = h / Rx U^(-1/2)); accurate to a few per cent over the range of
// their computations.  The asymptotes (rigid/elastic x isoviscous/piezoviscous)
// and their blending as stated in model.md.
namespace ehlsim {

/// Hc in Moes units for Moes load M, lubricant parameter L and D = Rx / Ry.
[[nodiscard]] double nvm_central_film(double M, double L, double D = 1.0);

/// The formula's rigid asymptotes (model.md), Moes units: rigid-isoviscous
/// H_RI = 145 (1 + 0.796 D^(14/15))^(-15/7) D^(-1) M^(-2) and
/// rigid-piezoviscous H_RP = 1.29 (1 + 0.691 D)^(-2/3) L^(2/3).
[[nodiscard]] double nvm_rigid_isoviscous_film(double M, double D = 1.0);
[[nodiscard]] double nvm_rigid_piezoviscous_film(double L, double D = 1.0);
/// The formula with its elastic terms dropped, for rigid bodies: its limit
/// M -> 0, where s -> 3, is (H_RI^3 + H_RP^3)^(1/3).
[[nodiscard]] double nvm_rigid_central_film(double M, double L, double D = 1.0);

/// H (Hertz units, h Rx / a^2) of a film given in Moes units, and back:
/// H_Moes = H (3 M / 2)^(2/3) (model.md).
[[nodiscard]] double moes_to_hertz_film(double h_moes, double M);
[[nodiscard]] double hertz_to_moes_film(double H, double M);

}  // namespace ehlsim
