#include "rheology/Lubricant.hpp"

#include <cmath>
#include <stdexcept>

namespace ehlsim {

double Lubricant::roelands_z_from_alpha(double alpha_per_Pa, double eta0) {
  const double lnterm = std::log(eta0) + kRoelandsLnEtaInf;
  // ln(eta0) + 9.67 <= 0 means eta0 <= eta_inf: Roelands is meaningless there.
  if (!(eta0 > 0.0) || !(lnterm > 0.0))
    throw std::invalid_argument("roelands_z_from_alpha: eta0 must exceed 6.31e-5 Pa s");
  return alpha_per_Pa * kRoelandsP0_Pa / lnterm;
}

void Lubricant::validate() const {
  if (viscosity == ViscosityModel::Barus && !(alpha_bar >= 0.0))
    throw std::invalid_argument("Lubricant: Barus needs alpha_bar >= 0");
  if (viscosity == ViscosityModel::Roelands) {
    if (!(eta0_Pa_s > 0.0) || !(std::log(eta0_Pa_s) + kRoelandsLnEtaInf > 0.0))
      throw std::invalid_argument("Lubricant: Roelands needs eta0 > 6.31e-5 Pa s");
    if (!(roelands_z > 0.0)) throw std::invalid_argument("Lubricant: Roelands needs z > 0");
  }
  const bool needs_ph =
      viscosity == ViscosityModel::Roelands || density == DensityModel::DowsonHigginson;
  if (needs_ph && !(ph_star_Pa > 0.0))
    throw std::invalid_argument("Lubricant: Roelands / Dowson-Higginson need ph* > 0");
}

}  // namespace ehlsim
