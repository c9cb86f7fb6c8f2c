#pragma once
// The dry (unlubricated) Hertz impact in the model's units: the limit the
// lubricated impact must approach for large M (model.md, "Reference values").
#include <limits>
#include <vector>

namespace ehlsim {

/// Hertz contact force for the separation Delta: (2 pi / 3)(-Delta)^(3/2) in
/// contact (Delta < 0), 0 otherwise; so that the acceleration is (-Delta)^(3/2).
[[nodiscard]] double dry_hertz_force(double Delta);

/// Hertz contact radius A = sqrt(-Delta) (0 out of contact).
[[nodiscard]] double dry_contact_radius(double Delta);

/// Duration of the dry contact at V0 = 1 in units of t_bar: model.md,
/// "Reference values" (1.0000 -> 4.2181; the paper's 3.218).
inline constexpr double kDryContactDuration = 3.2181;

/// Duration of the dry contact of a ball arriving at speed V0 (in v0):
/// 3.2181 V0^(-1/5), the Hertz scaling of the contact time.
[[nodiscard]] double dry_contact_duration(double V0);

/// Largest approach -Delta of the dry impact whose energy (ball and solids)
/// is E, in the model's units: (5/2 E)^(2/5); 1.0934 for E = 1/2 (model.md).
[[nodiscard]] double dry_largest_approach(double energy);

/// Largest dry contact radius of a ball arriving at speed V0:
/// sqrt(dry_largest_approach(V0^2 / 2)) = 1.0456 V0^(2/5).
[[nodiscard]] double dry_largest_contact_radius(double V0);

struct DryImpact {
  std::vector<double> T, Delta, V;  ///< every time level, from T = 0 to the end
  static constexpr double kUnset = std::numeric_limits<double>::quiet_NaN();
  double T_contact = kUnset;      ///< Delta crosses 0 downwards (0 if Delta0 < 0; NaN if never)
  double T_lift_off = kUnset;     ///< Delta crosses 0 upwards after contact (NaN if never)
  double Delta_min = kUnset;      ///< minimum (turning point) of the trajectory (NaN if none)
  double T_Delta_min = kUnset;    ///< its time
  double rebound_speed = kUnset;  ///< dDelta/dT after lift-off (NaN without lift-off)
  double impulse = 0.0;           ///< (3/(2 pi)) Int F dT = Int A dT (trapezoidal rule)
};

/// Integrates the dry impact from Delta(0) = Delta0, dDelta/dT(0) = -V0 with
/// the Newmark scheme (the one the lubricated solver uses) and step dT, until
/// the step after lift-off or T_end_max.  Each implicit step
/// Delta_new = delta_for_force(s, F(Delta_new)) is solved by safeguarded
/// Newton to 1e-14.
///
/// Crossings of Delta = 0 are interpolated linearly within the step: outside
/// contact the motion is uniform and just inside it the force grows like
/// |T - T0|^(3/2), so the interpolation error is O(dT^(7/2)), far below the
/// O(dT^2) of the scheme.  The minimum is that of the cubic Hermite
/// interpolant (Delta, V at both ends of the step), O(dT^4).
/// Throws std::invalid_argument for dT <= 0 or a non-finite T_end_max.
[[nodiscard]] DryImpact simulate_dry_hertz(double Delta0, double V0, double dT, double T_end_max);

}  // namespace ehlsim
