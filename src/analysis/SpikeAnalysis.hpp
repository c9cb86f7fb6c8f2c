#pragma once
// The pressure-spike analysis of section 3 of Lubrecht & Venner (2022), as
// pure functions on array views (docs/model.md, "Spike analysis"):
//
//   every point of the quadrant X >= 0, Y >= 0 -> (R, P) sorted by R
//   -> moving average over `smoothing_points` points
//   -> linear resampling onto a uniform R grid
//   -> zero-phase low-pass filter (forward-backward Butterworth or Gaussian)
//   -> the spike: the outermost prominent local maximum beyond R = 0.
//
// The same rule, without filtering, gives the spike position on the axis
// Y = 0 (the paper's P(X)) for comparison.
#include <optional>
#include <span>
#include <vector>

#include "analysis/SpikeSettings.hpp"
#include "grid/Grid.hpp"

namespace ehlsim {

/// Samples of a function of one coordinate, sorted by position.
struct Profile {
  std::vector<double> position;
  std::vector<double> value;
  [[nodiscard]] std::size_t size() const { return position.size(); }
};

/// (R, P) of every grid point with X >= 0, Y >= 0 and R <= half_width (beyond
/// the inscribed circle the quadrant no longer covers every direction), sorted
/// by R (ties in grid order).  P is a field on `grid` (row-major, j * n + i).
[[nodiscard]] Profile quadrant_radial_profile(const Grid2D& grid, std::span<const double> P);

/// The points of quadrant_radial_profile in the order of their R.  The order
/// depends on the grid only: a run sorts once and gathers the pressure of
/// each step (sorting the 1025^2 quadrant at every step took 1.5 % of a run,
/// on one thread while the other waited).
class RadialOrder {
 public:
  RadialOrder() = default;
  explicit RadialOrder(const Grid2D& grid);
  [[nodiscard]] const Grid2D& grid() const { return grid_; }
  /// The sorted (R, P) of P, a field on grid().
  [[nodiscard]] Profile profile(std::span<const double> P) const;

 private:
  Grid2D grid_;
  std::vector<double> radius_;      // sorted
  std::vector<std::size_t> index_;  // the grid index of each radius_
};

/// P(X) along Y = 0 for X >= 0 (grid.n must be odd so that Y = 0 is a grid line).
[[nodiscard]] Profile axis_profile(const Grid2D& grid, std::span<const double> P);

/// Average of `points` consecutive samples around each sample, positions and
/// values alike (averaging the positions too keeps a linear P(R) exact on
/// unevenly spaced R).  Within points / 2 of either end the window shrinks to
/// stay centred on its sample, so the first sample (R = 0) is kept as it is;
/// and it is narrowed (about its sample) until it spans at most `max_width`
/// in position (0: every sample alone).
[[nodiscard]] Profile moving_average(const Profile& profile, int points, double max_width);

/// The profile by linear interpolation at 0, spacing, 2 spacing, ... up to its
/// last position; constant before its first sample.
[[nodiscard]] Profile resample_uniform(const Profile& profile, double spacing);

/// Zero-phase low-pass filter of samples at uniform `spacing` from position 0:
/// amplitude 1/2 at `cutoff_wavelength` (both kinds).  The ends are extended
/// before filtering: mirrored about the first sample (P(R) is even in R) and
/// constant after the last (the pressure-free outside).
[[nodiscard]] std::vector<double> low_pass(std::span<const double> values, double spacing,
                                           SpikeFilter filter, double cutoff_wavelength);

struct Peak {
  double position = 0.0;
  double value = 0.0;
};

/// The rule that picks the spike among the local maxima of a profile.
struct PeakRule {
  double min_height = 0.0;      ///< fraction of the profile's maximum
  double min_prominence = 0.0;  ///< fraction of the profile's maximum
  double min_top = 0.0;         ///< no peak where the profile's maximum is below this
  /// Locate the maximum between samples (parabola through the three samples
  /// around it, uniform spacing); otherwise report the sample itself.
  bool interpolate = true;
};

/// The outermost local maximum of a profile, excluding its first sample (the
/// centre), that passes `rule`; nullopt if there is none.
[[nodiscard]] std::optional<Peak> outermost_peak(const Profile& profile, const PeakRule& rule);

/// One pressure field analysed.
struct SpikeAnalysis {
  Profile filtered;            ///< the filtered P(R) on its uniform R grid
  Profile axis;                ///< P(X) on Y = 0, X >= 0
  std::optional<Peak> radial;  ///< the spike of the filtered P(R): R_s, P_s
  std::optional<Peak> axial;   ///< the spike of P(X) on Y = 0 (grid point)
};

[[nodiscard]] SpikeAnalysis analyze_spike(const RadialOrder& order, std::span<const double> P,
                                          const SpikeSettings& settings);
/// The same for one field (sorts its grid's points first).
[[nodiscard]] SpikeAnalysis analyze_spike(const Grid2D& grid, std::span<const double> P,
                                          const SpikeSettings& settings);

/// d r/d t at t1 from three points (second order on uneven spacing); NaN if
/// any input is NaN.
[[nodiscard]] double three_point_derivative(double t0, double t1, double t2, double r0, double r1,
                                            double r2);

/// One sample of r(t).
struct TimedValue {
  double t = 0.0;
  double r = 0.0;
};

/// d r/d t at `at` from its neighbours: the three-point difference with both,
/// the two-point one with only one of them (an end of the series), NaN with
/// neither.  The one rule of the batch (finite_difference_rate) and the
/// streaming (spike.csv) spike speed.
[[nodiscard]] double rate_at(const std::optional<TimedValue>& before, TimedValue at,
                             const std::optional<TimedValue>& after);

/// d r/d t at every sample by rate_at: three-point differences inside,
/// two-point at the ends (NaN where a needed value is NaN, or for fewer than
/// two samples).
[[nodiscard]] std::vector<double> finite_difference_rate(std::span<const double> t,
                                                         std::span<const double> r);

/// What spike.csv reports for one time (V_s, a derivative, is added by the writer).
struct SpikeSample {
  double T = 0.0;
  double R_s = 0.0;    ///< spike radius of the filtered P(R) (NaN: no spike)
  double P_s = 0.0;    ///< its filtered pressure (NaN: no spike)
  double A_dry = 0.0;  ///< dry Hertz contact radius at T
  double X_s = 0.0;    ///< spike position on Y = 0, a grid point (NaN: no spike)
  double P_xs = 0.0;   ///< P there (NaN: no spike)
};

class DryContactRadius;

/// The sample of one analysed field at time T.
[[nodiscard]] SpikeSample spike_sample(double T, const SpikeAnalysis& analysis,
                                       const DryContactRadius& dry);

/// The dry Hertz contact radius A_dry(T) = sqrt(-Delta_dry(T)) of a ball with
/// the same Delta0, V0, on the same time axis (docs/model.md: no shift).
class DryContactRadius {
 public:
  DryContactRadius(double Delta0, double V0);
  /// 0 before contact and after lift-off.
  [[nodiscard]] double at(double T) const;
  [[nodiscard]] double T_contact() const { return T_contact_; }
  [[nodiscard]] double T_lift_off() const { return T_lift_off_; }
  /// Time levels stored (bounded for every Delta0 and V0).
  [[nodiscard]] std::size_t table_size() const { return T_.size(); }

 private:
  std::vector<double> T_, Delta_;
  double T_contact_ = 0.0;
  double T_lift_off_ = 0.0;
};

}  // namespace ehlsim
