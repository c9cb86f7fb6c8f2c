#pragma once
// The physical test case shared by the scaling and io tests (and the one of
// examples/physical.toml): a steel ball of 10 mm radius, 7850 kg/m^3, on a
// steel flat (E = 210 GPa, nu = 0.3), at 0.1 m/s, eta0 = 0.04 Pa s,
// alpha = 2e-8 1/Pa.
#include "impact/Scaling.hpp"

namespace ehlsim::testing {

inline PhysicalCase steel_ball() {
  PhysicalCase p;
  p.reduced_radius_m = 0.01;
  p.mass_kg = sphere_mass(0.01, 7850.0);
  p.impact_speed_m_s = 0.1;
  p.reduced_modulus_Pa = reduced_modulus(210e9, 0.3, 210e9, 0.3);
  p.eta0_Pa_s = 0.04;
  p.alpha_per_Pa = 2e-8;
  return with_reference_scales(p);
}

}  // namespace ehlsim::testing
