#include "analysis/SpikeAnalysis.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <numeric>
#include <stdexcept>

#include "dynamics/DryHertz.hpp"

namespace ehlsim {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

/// The ends are extended by this many cut-off wavelengths before filtering: the
/// start-up transient of the recursive filter, and the Gaussian weights (which
/// end at one cut-off wavelength), die out well within it.
constexpr double kPadWavelengths = 3.0;

/// Butterworth quality factor 1/sqrt(2): the maximally flat second-order
/// low-pass (R. Bristow-Johnson, "Cookbook formulae for audio EQ biquad filter
/// coefficients", low-pass with Q = 1/sqrt(2)).
const double kButterworthQ = 1.0 / std::numbers::sqrt2;

/// ISO 16610-21 Gaussian profile filter: weights exp(-pi (x / (alpha lc))^2) /
/// (alpha lc) with alpha = sqrt(ln 2 / pi), which pass the cut-off wavelength
/// lc with amplitude 1/2.  Truncated at |x| = lc (the weight there is 6e-7).
const double kGaussianAlpha = std::sqrt(std::numbers::ln2 / std::numbers::pi);
constexpr double kGaussianSupportWavelengths = 1.0;

/// Dry trajectory step: Newmark at 1e-3 gives the lift-off time to 3e-7
/// (docs/validation.md, dry Hertz impact), far below any mesh size used.
constexpr double kDryTimeStep = 1e-3;
/// Most steps of the dry trajectory over one contact duration (a table of at
/// most about 2^19 time levels, 12 MB, for any V0).
constexpr double kMaxDryContactSteps = 1 << 18;
/// The dry trajectory ends with the step after lift-off; its horizon, this
/// many contact durations plus kDryHorizonMargin, only caps it.  The table
/// starts less than one step before contact, so lift-off comes at one
/// duration: the cap is never what ends it.
constexpr double kDryHorizonDurations = 2.0;
constexpr double kDryHorizonMargin = 1.0;

/// values, padded: `pad` mirrored samples before (v[pad], ..., v[1]) and `pad`
/// copies of the last sample after.
std::vector<double> padded(std::span<const double> values, std::size_t pad) {
  const std::size_t n = values.size();
  std::vector<double> out;
  out.reserve(n + 2 * pad);
  for (std::size_t k = pad; k >= 1; --k) out.push_back(values[std::min(k, n - 1)]);
  out.insert(out.end(), values.begin(), values.end());
  out.insert(out.end(), pad, values.back());
  return out;
}

/// One pass of the biquad (direct form II transposed), started in the steady
/// state of its first input so that a constant passes unchanged.
void biquad_pass(std::vector<double>& x, const double b[3], const double a[3]) {
  double z2 = (b[2] - a[2]) * x.front();
  double z1 = (b[1] - a[1]) * x.front() + z2;
  for (double& v : x) {
    const double in = v;
    const double out = b[0] * in + z1;
    z1 = b[1] * in - a[1] * out + z2;
    z2 = b[2] * in - a[2] * out;
    v = out;
  }
}

std::vector<double> butterworth_forward_backward(std::vector<double> x, double spacing,
                                                 double cutoff_wavelength) {
  // Second-order Butterworth by the bilinear transform (cookbook low-pass):
  // -3 dB at the cut-off per pass, so -6 dB (amplitude 1/2) forward and back.
  const double w0 = 2.0 * std::numbers::pi * spacing / cutoff_wavelength;
  const double alpha = std::sin(w0) / (2.0 * kButterworthQ);
  const double c = std::cos(w0);
  const double a0 = 1.0 + alpha;
  const double b[3] = {(1.0 - c) / (2.0 * a0), (1.0 - c) / a0, (1.0 - c) / (2.0 * a0)};
  const double a[3] = {1.0, -2.0 * c / a0, (1.0 - alpha) / a0};
  biquad_pass(x, b, a);
  std::reverse(x.begin(), x.end());
  biquad_pass(x, b, a);
  std::reverse(x.begin(), x.end());
  return x;
}

std::vector<double> gaussian_smooth(const std::vector<double>& x, std::size_t pad, double spacing,
                                    double cutoff_wavelength) {
  const double scale = kGaussianAlpha * cutoff_wavelength;
  const auto half = static_cast<std::size_t>(
      std::ceil(kGaussianSupportWavelengths * cutoff_wavelength / spacing));
  std::vector<double> weight(half + 1);
  for (std::size_t k = 0; k <= half; ++k) {
    const double s = static_cast<double>(k) * spacing / scale;
    weight[k] = std::exp(-std::numbers::pi * s * s);
  }
  const double total = 2.0 * std::accumulate(weight.begin(), weight.end(), 0.0) - weight[0];
  for (double& w : weight) w /= total;
  std::vector<double> out(x.size(), 0.0);
  // Only the unpadded samples are needed; pad >= half keeps the window inside.
  for (std::size_t i = pad; i + pad < x.size(); ++i) {
    double sum = weight[0] * x[i];
    for (std::size_t k = 1; k <= half; ++k) sum += weight[k] * (x[i - k] + x[i + k]);
    out[i] = sum;
  }
  return out;
}

}  // namespace

RadialOrder::RadialOrder(const Grid2D& grid) : grid_(grid) {
  const int centre = (grid.n - 1) / 2;
  struct Sample {
    double R;
    std::size_t index;
  };
  std::vector<Sample> samples;
  for (int j = centre; j < grid.n; ++j) {
    for (int i = centre; i < grid.n; ++i) {
      const double R = std::hypot(grid.x(i), grid.y(j));
      if (R <= grid.half_width) samples.push_back({R, grid.index(i, j)});
    }
  }
  std::stable_sort(samples.begin(), samples.end(),
                   [](const Sample& a, const Sample& b) { return a.R < b.R; });
  radius_.reserve(samples.size());
  index_.reserve(samples.size());
  for (const Sample& s : samples) {
    radius_.push_back(s.R);
    index_.push_back(s.index);
  }
}

Profile RadialOrder::profile(std::span<const double> P) const {
  if (P.size() != grid_.size()) throw std::invalid_argument("quadrant_radial_profile: field size");
  Profile out;
  out.position = radius_;
  out.value.reserve(index_.size());
  for (const std::size_t k : index_) out.value.push_back(P[k]);
  return out;
}

Profile quadrant_radial_profile(const Grid2D& grid, std::span<const double> P) {
  return RadialOrder(grid).profile(P);
}

Profile axis_profile(const Grid2D& grid, std::span<const double> P) {
  if (P.size() != grid.size()) throw std::invalid_argument("axis_profile: field size");
  if (grid.n % 2 == 0) throw std::invalid_argument("axis_profile: Y = 0 is not a grid line");
  const int centre = (grid.n - 1) / 2;
  Profile out;
  for (int i = centre; i < grid.n; ++i) {
    out.position.push_back(grid.x(i));
    out.value.push_back(P[grid.index(i, centre)]);
  }
  return out;
}

Profile moving_average(const Profile& profile, int points, double max_width) {
  if (points < 1) throw std::invalid_argument("moving_average: points must be >= 1");
  // 0 is the limit of narrow windows: one sample each.  spike.max_window_meshes
  // may be any positive double, whose product with the mesh can round to 0.
  if (!(max_width >= 0.0)) throw std::invalid_argument("moving_average: max_width must be >= 0");
  const std::size_t n = profile.size();
  const auto m = static_cast<std::size_t>(points);
  // Prefix sums: the mean of [lo, hi] in O(1).
  std::vector<double> sum_position(n + 1, 0.0);
  std::vector<double> sum_value(n + 1, 0.0);
  for (std::size_t k = 0; k < n; ++k) {
    sum_position[k + 1] = sum_position[k] + profile.position[k];
    sum_value[k + 1] = sum_value[k] + profile.value[k];
  }
  Profile out;
  out.position.resize(n);
  out.value.resize(n);
  const std::size_t before_full = (m - 1) / 2;  // window [k - before, k + after]
  const std::size_t after_full = m - 1 - before_full;
  for (std::size_t k = 0; k < n; ++k) {
    // Near the ends the window shrinks symmetrically about k: at R = 0 the
    // points are sparse and a one-sided window would shift the centre value.
    std::size_t before = before_full;
    std::size_t after = after_full;
    if (k < before_full || n - 1 - k < after_full) before = after = std::min(k, n - 1 - k);
    // Where the points are sparse in R (near the centre) the window is also
    // narrowed to max_width, so that it does not smear what the grid resolves.
    while ((before > 0 || after > 0) &&
           profile.position[k + after] - profile.position[k - before] > max_width) {
      if (after >= before) {
        --after;
      } else {
        --before;
      }
    }
    const auto count = static_cast<double>(before + after + 1);
    out.position[k] = (sum_position[k + after + 1] - sum_position[k - before]) / count;
    out.value[k] = (sum_value[k + after + 1] - sum_value[k - before]) / count;
  }
  return out;
}

Profile resample_uniform(const Profile& profile, double spacing) {
  if (!(spacing > 0.0)) throw std::invalid_argument("resample_uniform: spacing must be > 0");
  Profile out;
  if (profile.size() == 0) return out;
  const double last = profile.position.back();
  const auto count = static_cast<std::size_t>(std::floor(last / spacing)) + 1;
  out.position.reserve(count);
  out.value.reserve(count);
  std::size_t k = 0;  // profile.position[k] <= x < profile.position[k + 1]
  for (std::size_t m = 0; m < count; ++m) {
    const double x = static_cast<double>(m) * spacing;
    double v = profile.value.front();
    if (x >= profile.position.front()) {
      while (k + 2 < profile.size() && profile.position[k + 1] <= x) ++k;
      const double x0 = profile.position[k];
      const double x1 = k + 1 < profile.size() ? profile.position[k + 1] : x0;
      const double v0 = profile.value[k];
      const double v1 = k + 1 < profile.size() ? profile.value[k + 1] : v0;
      v = x1 > x0 ? v0 + (v1 - v0) * std::clamp((x - x0) / (x1 - x0), 0.0, 1.0) : v1;
    }
    out.position.push_back(x);
    out.value.push_back(v);
  }
  return out;
}

std::vector<double> low_pass(std::span<const double> values, double spacing, SpikeFilter filter,
                             double cutoff_wavelength) {
  if (values.empty() || filter == SpikeFilter::None) return {values.begin(), values.end()};
  if (!(spacing > 0.0) || !(cutoff_wavelength > 2.0 * spacing)) {
    throw std::invalid_argument("low_pass: the cut-off wavelength must exceed two sample spacings");
  }
  const auto pad =
      static_cast<std::size_t>(std::ceil(kPadWavelengths * cutoff_wavelength / spacing));
  const std::vector<double> x = padded(values, pad);
  const std::vector<double> y = filter == SpikeFilter::Gaussian
                                    ? gaussian_smooth(x, pad, spacing, cutoff_wavelength)
                                    : butterworth_forward_backward(x, spacing, cutoff_wavelength);
  return {y.begin() + static_cast<std::ptrdiff_t>(pad),
          y.begin() + static_cast<std::ptrdiff_t>(pad + values.size())};
}

std::optional<Peak> outermost_peak(const Profile& profile, const PeakRule& rule) {
  const std::vector<double>& v = profile.value;
  const std::size_t n = v.size();
  if (n < 3) return std::nullopt;
  const double top = *std::max_element(v.begin(), v.end());
  if (!(top > 0.0) || top < rule.min_top) return std::nullopt;
  for (std::size_t m = n - 2; m >= 1; --m) {
    const bool local_max = v[m] > v[m - 1] && v[m] >= v[m + 1];
    if (!local_max || v[m] < rule.min_height * top) continue;
    // Inward prominence: the lowest point before the profile rises above v[m] again.
    double lowest = v[m];
    for (std::size_t k = m; k-- > 0 && v[k] <= v[m];) lowest = std::min(lowest, v[k]);
    if (v[m] - lowest < rule.min_prominence * top) continue;
    Peak peak{profile.position[m], v[m]};
    if (rule.interpolate) {
      const double curvature = v[m - 1] - 2.0 * v[m] + v[m + 1];
      if (curvature < 0.0) {
        const double offset = 0.5 * (v[m - 1] - v[m + 1]) / curvature;  // in samples, |.| <= 1/2
        const double spacing = profile.position[m + 1] - profile.position[m];
        peak.position += offset * spacing;
        peak.value -= 0.25 * (v[m - 1] - v[m + 1]) * offset;
      }
    }
    return peak;
  }
  return std::nullopt;
}

SpikeAnalysis analyze_spike(const Grid2D& grid, std::span<const double> P,
                            const SpikeSettings& settings) {
  return analyze_spike(RadialOrder(grid), P, settings);
}

SpikeAnalysis analyze_spike(const RadialOrder& order, std::span<const double> P,
                            const SpikeSettings& settings) {
  const Grid2D& grid = order.grid();
  const double h = grid.h();
  SpikeAnalysis out;
  const Profile averaged =
      moving_average(order.profile(P), settings.smoothing_points, settings.max_window_meshes * h);
  out.filtered = resample_uniform(averaged, settings.resample_meshes * h);
  out.filtered.value = low_pass(out.filtered.value, settings.resample_meshes * h, settings.filter,
                                settings.cutoff_meshes * h);
  out.axis = axis_profile(grid, P);
  const PeakRule rule{settings.min_height, settings.min_prominence, settings.min_pressure, true};
  out.radial = outermost_peak(out.filtered, rule);
  // The same rule on the axis, where the position is a grid point.
  PeakRule axial_rule = rule;
  axial_rule.interpolate = false;
  out.axial = outermost_peak(out.axis, axial_rule);
  return out;
}

SpikeSample spike_sample(double T, const SpikeAnalysis& analysis, const DryContactRadius& dry) {
  SpikeSample s;
  s.T = T;
  s.R_s = analysis.radial ? analysis.radial->position : kNaN;
  s.P_s = analysis.radial ? analysis.radial->value : kNaN;
  s.A_dry = dry.at(T);
  s.X_s = analysis.axial ? analysis.axial->position : kNaN;
  s.P_xs = analysis.axial ? analysis.axial->value : kNaN;
  return s;
}

double three_point_derivative(double t0, double t1, double t2, double r0, double r1, double r2) {
  const double a = t1 - t0;
  const double b = t2 - t1;
  // Derivative at t1 of the parabola through the three points.
  return (-b / (a * (a + b))) * r0 + ((b - a) / (a * b)) * r1 + (a / (b * (a + b))) * r2;
}

double rate_at(const std::optional<TimedValue>& before, TimedValue at,
               const std::optional<TimedValue>& after) {
  if (before && after)
    return three_point_derivative(before->t, at.t, after->t, before->r, at.r, after->r);
  if (before) return (at.r - before->r) / (at.t - before->t);
  if (after) return (after->r - at.r) / (after->t - at.t);
  return kNaN;
}

std::vector<double> finite_difference_rate(std::span<const double> t, std::span<const double> r) {
  if (t.size() != r.size()) throw std::invalid_argument("finite_difference_rate: sizes differ");
  const std::size_t n = t.size();
  std::vector<double> rate(n, kNaN);
  if (n < 2) return rate;
  for (std::size_t k = 0; k < n; ++k) {
    const std::optional<TimedValue> before =
        k > 0 ? std::optional<TimedValue>({t[k - 1], r[k - 1]}) : std::nullopt;
    const std::optional<TimedValue> after =
        k + 1 < n ? std::optional<TimedValue>({t[k + 1], r[k + 1]}) : std::nullopt;
    rate[k] = rate_at(before, {t[k], r[k]}, after);
  }
  return rate;
}

DryContactRadius::DryContactRadius(double Delta0, double V0) {
  // Out of contact the ball flies at -V0 (no force): the trajectory starts at
  // the last step on the kDryTimeStep grid before contact, however far away
  // the ball starts, and its table spans the contact only.  Very slow impacts
  // last long (V0^-0.2): their step grows so that the table stays bounded.
  const double duration = dry_contact_duration(V0);
  const double dt = std::max(kDryTimeStep, duration / kMaxDryContactSteps);
  const double free_steps = std::floor(std::max(Delta0, 0.0) / (V0 * dt));
  const double T_start = free_steps * dt;
  const double horizon = kDryHorizonDurations * duration + kDryHorizonMargin;
  DryImpact dry = simulate_dry_hertz(Delta0 - V0 * T_start, V0, dt, horizon);
  T_ = std::move(dry.T);
  for (double& T : T_) T += T_start;
  Delta_ = std::move(dry.Delta);
  T_contact_ = dry.T_contact + T_start;
  T_lift_off_ = dry.T_lift_off + T_start;
}

double DryContactRadius::at(double T) const {
  if (T_.empty() || T < T_.front() || T > T_.back()) return 0.0;
  const auto upper = std::upper_bound(T_.begin(), T_.end(), T);
  if (upper == T_.end()) return dry_contact_radius(Delta_.back());
  const auto k = static_cast<std::size_t>(upper - T_.begin()) - 1;
  const double w = (T - T_[k]) / (T_[k + 1] - T_[k]);
  return dry_contact_radius((1.0 - w) * Delta_[k] + w * Delta_[k + 1]);
}

}  // namespace ehlsim
