#include "dynamics/Newmark.hpp"

#include <cmath>
#include <stdexcept>

namespace ehlsim {

Newmark::Newmark(double dT) : dT_(dT) {
  if (!(dT > 0.0) || !std::isfinite(dT))
    throw std::invalid_argument("Newmark: the time step must be positive and finite");
}

BallState Newmark::advance(const BallState& s, double force_new) const {
  const double a_new = kForceToAcceleration * force_new;
  BallState next;
  next.T = s.T + dT_;
  next.Delta = delta_for_force(s, force_new);
  next.V = s.V + dT_ * ((1.0 - kGamma) * s.A + kGamma * a_new);
  next.A = a_new;
  return next;
}

}  // namespace ehlsim
