#include "rolling/FilmFormula.hpp"

#include <algorithm>
#include <cmath>

namespace ehlsim {

double nvm_central_film(double M, double L, double D) {
  using std::exp;
  using std::log;
  using std::pow;
  // Rigid-isoviscous, elastic-isoviscous, rigid-piezoviscous and
  // elastic-piezoviscous asymptotes.
  const double h_ri = nvm_rigid_isoviscous_film(M, D);
  const double ellipse = 1.0 + 0.006 * log(D) + 0.63 * pow(D, 4.0 / 7.0);
  const double h_ei = 3.18 * pow(ellipse, -14.0 / 25.0) * pow(D, -1.0 / 15.0) * pow(M, -2.0 / 15.0);
  const double h_rp = nvm_rigid_piezoviscous_film(L, D);
  const double h_ep =
      1.48 * pow(ellipse, -7.0 / 20.0) * pow(D, -1.0 / 24.0) * pow(M, -1.0 / 12.0) * pow(L, 0.75);
  const double h_00 = 1.8 / D;
  const double s = 1.5 * (1.0 + exp(-1.2 * h_ei / h_ri));
  const double isoviscous =
      pow(pow(h_ri, 1.5) + pow(pow(h_ei, -4.0) + pow(h_00, -4.0), -3.0 / 8.0), 2.0 * s / 3.0);
  // L = 0: the piezoviscous asymptotes vanish and so does their term.
  const double piezoviscous = L > 0.0 ? pow(pow(h_rp, -8.0) + pow(h_ep, -8.0), -s / 8.0) : 0.0;
  return pow(isoviscous + piezoviscous, 1.0 / s);
}

double nvm_rigid_isoviscous_film(double M, double D) {
  return 145.0 * std::pow(1.0 + 0.796 * std::pow(D, 14.0 / 15.0), -15.0 / 7.0) / D / (M * M);
}

double nvm_rigid_piezoviscous_film(double L, double D) {
  return 1.29 * std::pow(1.0 + 0.691 * D, -2.0 / 3.0) * std::pow(L, 2.0 / 3.0);
}

double nvm_rigid_central_film(double M, double L, double D) {
  const double isoviscous = nvm_rigid_isoviscous_film(M, D);
  const double piezoviscous = nvm_rigid_piezoviscous_film(L, D);
  const double sum = std::pow(isoviscous, 3.0) + std::pow(piezoviscous, 3.0);
  if (std::isnormal(sum)) return std::cbrt(sum);
  // The cubes overflow from films of 6e102 on (case.D = 1e-150 gave inf) or
  // underflow below 3e-103: scaled by the larger film they do not.
  const double larger = std::max(isoviscous, piezoviscous);
  if (!(larger > 0.0) || !std::isfinite(larger)) return larger;
  return larger *
         std::cbrt(std::pow(isoviscous / larger, 3.0) + std::pow(piezoviscous / larger, 3.0));
}

double moes_to_hertz_film(double h_moes, double M) { return h_moes / std::pow(1.5 * M, 2.0 / 3.0); }
double hertz_to_moes_film(double H, double M) { return H * std::pow(1.5 * M, 2.0 / 3.0); }

}  // namespace ehlsim
