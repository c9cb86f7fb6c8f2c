// The spike analysis (src/analysis/SpikeAnalysis): synthetic pressure fields
// with a known spike, the filters' cut-off, the finite differences and the
// dry contact radius.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <numbers>
#include <vector>

#include "analysis/SpikeAnalysis.hpp"
#include "grid/Grid.hpp"

namespace {

using namespace ehlsim;

constexpr int kPoints = 129;  // h = 3/128, the study's coarse grid
constexpr double kHalfWidth = 1.5;

/// A Hertz-like dome of radius A with a Gaussian bump (the spike) at R0.
struct SyntheticSpike {
  double A = 0.95;
  double amplitude = 0.3;
  double width = 0.035;  ///< standard deviation, 1.5 meshes of 129^2
  double R0 = 0.6;
  [[nodiscard]] double operator()(double R) const {
    const double dome = R < A ? std::sqrt(1.0 - (R / A) * (R / A)) : 0.0;
    const double s = (R - R0) / width;
    return dome + amplitude * std::exp(-0.5 * s * s);
  }
};

Field sample(const Grid2D& grid, const std::function<double(double)>& f) {
  Field P(grid);
  for (int j = 0; j < grid.n; ++j)
    for (int i = 0; i < grid.n; ++i) P(i, j) = f(std::hypot(grid.x(i), grid.y(j)));
  return P;
}

/// Where f is largest near `guess` (golden-section search on +-3 widths).
double true_maximum(const std::function<double(double)>& f, double guess, double half_range) {
  double a = guess - half_range;
  double b = guess + half_range;
  const double g = (std::sqrt(5.0) - 1.0) / 2.0;
  for (int k = 0; k < 200; ++k) {
    const double c = b - g * (b - a);
    const double d = a + g * (b - a);
    if (f(c) > f(d)) {
      b = d;
    } else {
      a = c;
    }
  }
  return 0.5 * (a + b);
}

TEST(SpikeAnalysis, BumpOnAHertzDomeIsFoundWithinAQuarterMesh) {
  const Grid2D grid(kPoints, kHalfWidth);
  const double h = grid.h();
  for (const SpikeFilter filter : {SpikeFilter::Butterworth, SpikeFilter::Gaussian}) {
    for (const double R0 : {0.12, 0.3, 0.55, 0.77}) {
      SyntheticSpike spike;
      spike.R0 = R0;
      SpikeSettings settings;
      settings.filter = filter;
      const SpikeAnalysis a = analyze_spike(grid, sample(grid, spike).span(), settings);
      ASSERT_TRUE(a.radial.has_value()) << "R0 = " << R0;
      const double expected = true_maximum(spike, R0, 3.0 * spike.width);
      EXPECT_NEAR(a.radial->position, expected, 0.25 * h)
          << "R0 = " << R0 << ", filter " << static_cast<int>(filter);
      // On the axis the position is a grid point: within half a mesh.
      ASSERT_TRUE(a.axial.has_value());
      EXPECT_NEAR(a.axial->position, expected, 0.5 * h + 1e-12);
    }
  }
}

TEST(SpikeAnalysis, ADomeWithoutBumpHasNoSpike) {
  const Grid2D grid(kPoints, kHalfWidth);
  SyntheticSpike dome;
  dome.amplitude = 0.0;
  const SpikeAnalysis a = analyze_spike(grid, sample(grid, dome).span(), SpikeSettings{});
  EXPECT_FALSE(a.radial.has_value()) << a.radial->position;
  EXPECT_FALSE(a.axial.has_value());
}

// The field of the last step with pressure before lift-off: a spike profile
// scaled down to 1e-8 of the Hertz pressure.  The relative rules alone find
// its spike; spike.min_pressure says there is none.
TEST(SpikeAnalysis, AVanishingFieldHasNoSpike) {
  const Grid2D grid(kPoints, kHalfWidth);
  const SyntheticSpike spike;
  const Field P = sample(grid, [&](double R) { return 1e-8 * spike(R); });
  SpikeSettings relative_only;
  relative_only.min_pressure = 0.0;
  const SpikeAnalysis found = analyze_spike(grid, P.span(), relative_only);
  ASSERT_TRUE(found.radial.has_value());
  ASSERT_TRUE(found.axial.has_value());
  const SpikeAnalysis a = analyze_spike(grid, P.span(), SpikeSettings{});
  EXPECT_FALSE(a.radial.has_value()) << a.radial->position;
  EXPECT_FALSE(a.axial.has_value());
}

TEST(SpikeAnalysis, SpikeMovingAtAKnownSpeed) {
  const Grid2D grid(kPoints, kHalfWidth);
  const double dT = grid.h();  // as the solver: dT = h
  const double speed = -0.8;   // the rebound spike's order of magnitude (docs/validation.md)
  std::vector<double> T, R;
  for (int k = 0; k <= 16; ++k) {
    SyntheticSpike spike;
    spike.R0 = 0.75 + speed * k * dT;
    T.push_back(k * dT);
    R.push_back(analyze_spike(grid, sample(grid, spike).span(), SpikeSettings{}).radial->position);
  }
  const std::vector<double> V = finite_difference_rate(T, R);
  // Three-point differences inside: within 2 %.  The two-point differences of
  // the first and last sample divide the same position errors by dT instead
  // of 2 dT: within twice that.
  for (std::size_t k = 0; k < V.size(); ++k) {
    const bool end = k == 0 || k + 1 == V.size();
    EXPECT_NEAR(V[k], speed, (end ? 0.04 : 0.02) * std::abs(speed)) << "T = " << T[k];
  }
}

TEST(SpikeAnalysis, OneRadialOrderServesEveryFieldOfItsGrid) {
  // A run sorts its grid's points once and gathers each step's pressure: two
  // different fields through one order give what a fresh sort of each gives,
  // and R^2 comes back as the square of the sorted radius.
  const Grid2D grid(kPoints, kHalfWidth);
  const RadialOrder order(grid);
  const Field dome = sample(grid, [](double R) { return R < 1.0 ? 1.0 - R * R : 0.0; });
  const Field bowl = sample(grid, [](double R) { return R * R; });
  for (const Field* P : {&dome, &bowl}) {
    const Profile gathered = order.profile(P->span());
    const Profile sorted = quadrant_radial_profile(grid, P->span());
    EXPECT_EQ(gathered.position, sorted.position);
    EXPECT_EQ(gathered.value, sorted.value);
  }
  const Profile squares = order.profile(bowl.span());
  for (std::size_t k = 0; k < squares.size(); ++k)
    EXPECT_NEAR(squares.value[k], squares.position[k] * squares.position[k], 1e-12);
  EXPECT_THROW((void)order.profile(std::span<const double>(bowl.span().data(), 3)),
               std::invalid_argument);
}

TEST(SpikeAnalysis, RadialProfileOfAnAxisymmetricField) {
  const Grid2D grid(kPoints, kHalfWidth);
  const auto f = [](double R) { return R < 1.0 ? std::pow(1.0 - R * R, 1.5) : 0.0; };
  const Field P = sample(grid, f);
  const Profile raw = quadrant_radial_profile(grid, P.span());
  ASSERT_GT(raw.size(), 0u);
  for (std::size_t k = 0; k < raw.size(); ++k) {
    ASSERT_DOUBLE_EQ(raw.value[k], f(raw.position[k]));
    if (k > 0) {
      ASSERT_LE(raw.position[k - 1], raw.position[k]);
    }
  }
  EXPECT_LE(raw.position.back(), kHalfWidth);
  // The whole chain: the filtered P(R) follows f.  Its error is the bias of
  // averaging a curved profile, 0.5 |f''| Var(R) over a window: the 20 points
  // of the moving average span dR = 20 / (pi R / (2 h^2)) (the density of a
  // quarter annulus), 0.1 at R = 0.06, so 0.5 * 3 * dR^2 / 12 = 1.3e-3 near
  // the centre (|f''| = 3), and below 1e-4 from R = 0.2 on; the filter adds
  // 0.5 |f''| (0.19 * 3 h)^2 = 2.5e-4 (ISO Gaussian sigma = 0.19 cut-off).
  for (const SpikeFilter filter : {SpikeFilter::Butterworth, SpikeFilter::Gaussian}) {
    SpikeSettings settings;
    settings.filter = filter;
    const SpikeAnalysis a = analyze_spike(grid, P.span(), settings);
    double worst_centre = 0.0;
    double worst = 0.0;
    for (std::size_t k = 0; k < a.filtered.size(); ++k) {
      const double R = a.filtered.position[k];
      if (R > 0.9) break;
      const double error = std::abs(a.filtered.value[k] - f(R));
      (R < 0.2 ? worst_centre : worst) = std::max(R < 0.2 ? worst_centre : worst, error);
    }
    EXPECT_LT(worst_centre, 2e-3) << static_cast<int>(filter);
    EXPECT_LT(worst, 5e-4) << static_cast<int>(filter);
  }
}

TEST(SpikeAnalysis, MovingAverageWindow) {
  // Positions k^2 / 100: sparse at the end, dense at the start.  Values = positions,
  // so each averaged value equals its averaged position (a linear profile stays exact)
  // and the window of a sample can be read back from its averaged position.
  Profile p;
  for (int k = 0; k < 200; ++k) {
    p.position.push_back(k * k / 100.0);
    p.value.push_back(k * k / 100.0);
  }
  const double max_width = 5.0;
  const Profile a = moving_average(p, 20, max_width);
  ASSERT_EQ(a.size(), p.size());
  EXPECT_EQ(a.position.front(), 0.0);  // the first sample alone: the window stays centred
  for (std::size_t k = 0; k < a.size(); ++k) EXPECT_DOUBLE_EQ(a.value[k], a.position[k]);
  // Where 20 samples span less than max_width the window is the full 20 samples
  // (k = 10: samples 1..20, span 3.99); where they are sparse it is narrowed
  // (k = 150: spacing 3, so samples 149 and 150, span 2.99).
  double full = 0.0;
  for (int k = 1; k <= 20; ++k) full += k * k / 100.0;
  EXPECT_NEAR(a.position[10], full / 20.0, 1e-12);
  EXPECT_NEAR(a.position[150], 0.5 * (p.position[149] + p.position[150]), 1e-12);
}

// spike.max_window_meshes = 5e-324 times the mesh is 0: the run failed with
// "moving_average: max_width must be > 0" (exit 1) for a legal input.
TEST(SpikeAnalysis, AMovingAverageOfZeroWidthKeepsEverySample) {
  Profile p;
  for (int k = 0; k < 50; ++k) {
    p.position.push_back(0.1 * k);
    p.value.push_back(std::sin(0.3 * k));
  }
  const Profile a = moving_average(p, 20, 0.0);
  ASSERT_EQ(a.size(), p.size());
  for (std::size_t k = 0; k < a.size(); ++k) {  // differences of prefix sums: to rounding
    EXPECT_NEAR(a.position[k], p.position[k], 1e-14);
    EXPECT_NEAR(a.value[k], p.value[k], 1e-14);
  }
  EXPECT_THROW((void)moving_average(p, 20, -1.0), std::invalid_argument);
}

TEST(SpikeAnalysis, FiltersPassHalfTheAmplitudeAtTheCutOff) {
  const double spacing = 0.01;
  const double cutoff = 0.2;
  for (const SpikeFilter filter : {SpikeFilter::Butterworth, SpikeFilter::Gaussian}) {
    for (const double wavelength : {cutoff, 10.0 * cutoff}) {
      std::vector<double> x(2000);
      for (std::size_t k = 0; k < x.size(); ++k) {
        x[k] = std::cos(2.0 * std::numbers::pi * static_cast<double>(k) * spacing / wavelength);
      }
      const std::vector<double> y = low_pass(x, spacing, filter, cutoff);
      // Amplitude in the middle, away from the ends.
      double amplitude = 0.0;
      for (std::size_t k = 800; k < 1200; ++k) amplitude = std::max(amplitude, std::abs(y[k]));
      const double expected = wavelength == cutoff ? 0.5 : 1.0;
      EXPECT_NEAR(amplitude, expected, 0.02) << static_cast<int>(filter) << " " << wavelength;
    }
  }
}

TEST(SpikeAnalysis, ThreePointDerivativeIsExactForAParabola) {
  const auto r = [](double t) { return 2.0 - 3.0 * t + 0.7 * t * t; };
  const std::vector<double> t = {0.0, 0.1, 0.35, 0.4, 0.9};
  std::vector<double> values;
  for (const double ti : t) values.push_back(r(ti));
  const std::vector<double> rate = finite_difference_rate(t, values);
  for (std::size_t k = 1; k + 1 < t.size(); ++k) EXPECT_NEAR(rate[k], -3.0 + 1.4 * t[k], 1e-12);
  EXPECT_NEAR(rate.front(), (values[1] - values[0]) / 0.1, 1e-12);
}

TEST(SpikeAnalysis, DryContactRadiusOfModelMd) {
  // model.md, "Reference values": A(T) = sqrt(-Delta(T)) of the dry impact from Delta0 = V0 = 1.
  const DryContactRadius dry(1.0, 1.0);
  EXPECT_NEAR(dry.T_contact(), 1.0, 1e-9);
  EXPECT_NEAR(dry.T_lift_off(), 4.2181, 1e-4);
  EXPECT_NEAR(dry.at(1.5), 0.7000, 1e-4);
  EXPECT_NEAR(dry.at(3.223), 0.9424, 1e-4);
  EXPECT_NEAR(dry.at(3.574), 0.7874, 1e-4);
  EXPECT_NEAR(dry.at(4.0), 0.4664, 1e-4);
  EXPECT_EQ(dry.at(0.5), 0.0);
  EXPECT_EQ(dry.at(4.3), 0.0);
}

TEST(SpikeAnalysis, DryContactRadiusIsBoundedForRunawayStarts) {
  // The probes of issue 10 (time.Delta0 = 1e6, time.V0 = 1e-9) grew the table
  // by 400 MB/s: the free flight before contact is not tabulated, and a slow
  // impact takes longer steps.
  const std::size_t most = std::size_t{1} << 20;
  const DryContactRadius far(1e6, 1.0);
  EXPECT_NEAR(far.T_contact(), 1e6, 1e-6);
  EXPECT_NEAR(far.T_lift_off() - far.T_contact(), 3.2181, 1e-4);
  EXPECT_NEAR(far.at(1e6 + 2.223), 0.9424, 1e-4);  // the V0 = 1 contact, shifted
  EXPECT_EQ(far.at(5e5), 0.0);
  EXPECT_LT(far.table_size(), most);
  const DryContactRadius slow(1.0, 1e-9);
  EXPECT_NEAR(slow.T_contact(), 1e9, 1e-3);
  // Hertz: the contact lasts 3.2181 V0^-0.2 and reaches A = sqrt(1.0934 V0^0.8).
  const double duration = 3.2181 * std::pow(1e-9, -0.2);
  EXPECT_NEAR((slow.T_lift_off() - slow.T_contact()) / duration, 1.0, 1e-4);
  EXPECT_NEAR(slow.at(slow.T_contact() + 0.5 * duration) / std::sqrt(1.0934 * std::pow(1e-9, 0.8)),
              1.0, 1e-3);
  EXPECT_LT(slow.table_size(), most);
  // The default case keeps its fine table.
  EXPECT_LT(DryContactRadius(1.0, 1.0).table_size(), 10'000u);
}

}  // namespace
