#pragma once
// Time integration of the ball motion (model.md):
//   d^2 Delta / dT^2 = (3 / (2 pi)) F,   F = Int Int P dX dY (the film force).
// The Newmark scheme advances (Delta, V, A) for a given force at the new time
// level; the force itself depends on Delta (through the film), so the caller
// solves that implicit coupling, using delta_for_force() and d_delta_d_force().
#include <numbers>

namespace ehlsim {

/// Dimensionless acceleration per unit dimensionless force, 3/(2 pi): the
/// reference scales make m v0^2 = F* delta* (model.md, "Reference scales").
inline constexpr double kForceToAcceleration = 3.0 / (2.0 * std::numbers::pi);

struct BallState {
  double T = 0.0;      ///< time
  double Delta = 0.0;  ///< rigid-body separation (positive = apart)
  double V = 0.0;      ///< dDelta/dT (negative while approaching)
  double A = 0.0;      ///< d^2 Delta/dT^2
};

/// Newmark (1959) scheme with beta = 1/4, gamma = 1/2 ("average acceleration",
/// i.e. the trapezoidal rule): second order, unconditionally stable, no
/// numerical damping (energy is conserved exactly for a linear spring), so
/// any loss of rebound speed in a lubricated run is the film's, not the
/// integrator's.
class Newmark {
 public:
  static constexpr double kBeta = 0.25;  ///< Newmark (1959), average acceleration
  static constexpr double kGamma = 0.5;  ///< Newmark (1959): no numerical damping

  /// Throws std::invalid_argument unless dT > 0 and finite.
  explicit Newmark(double dT);

  [[nodiscard]] double dT() const { return dT_; }

  /// Delta at T + dT if the force at T + dT is force_new:
  ///   Delta + dT V + dT^2 [(1/2 - beta) A + beta a_new],  a_new = (3/(2 pi)) force_new.
  [[nodiscard]] double delta_for_force(const BallState& s, double force_new) const {
    return s.Delta + dT_ * s.V +
           dT_ * dT_ * ((0.5 - kBeta) * s.A + kBeta * kForceToAcceleration * force_new);
  }

  /// d(delta_for_force)/d(force_new) = beta dT^2 (3/(2 pi)): constant, positive.
  [[nodiscard]] double d_delta_d_force() const { return kBeta * dT_ * dT_ * kForceToAcceleration; }

  /// The state at T + dT for the force force_new at T + dT.
  [[nodiscard]] BallState advance(const BallState& s, double force_new) const;

 private:
  double dT_;
};

}  // namespace ehlsim
