// The parameters of `ehlsim impact`: its registry, load_config and the echo
// of an ImpactConfig.
#include "config/Parameters.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <utility>

#include "config/ParameterSet.hpp"
#include "dynamics/DryHertz.hpp"
#include "grid/Grid.hpp"
#include "grid/NumberText.hpp"
#include "impact/RunGuards.hpp"
#include "impact/Scaling.hpp"
#include "rheology/Lubricant.hpp"

namespace ehlsim {

namespace {

constexpr double kPoissonMax = 0.5;
// The defaults are those of ImpactConfig: declared once, there.
const ImpactConfig kDefaults{};
const double kDefaultM = kDefaults.M;
const double kDefaultL = kDefaults.L;
const int kDefaultGridPoints = kDefaults.grid_points;
const double kDefaultHalfWidth = kDefaults.half_width;
const double kDefaultDelta0 = kDefaults.Delta0;
const double kDefaultV0 = kDefaults.V0;
const double kDefaultWavelength = kDefaults.waviness_wavelength;
/// The waviness angle's range, [-kFullTurnDeg, kFullTurnDeg] degrees.
constexpr double kFullTurnDeg = 360.0;
const int kDefaultSnapshotEvery = kDefaults.snapshot_every;
constexpr std::string_view kSymmetryAuto = "auto";
constexpr std::string_view kSymmetryOff = "off";

// [spike] and output.snapshot_start: the settings of the spike analysis
// (analysis/SpikeSettings.hpp; docs/model.md, "Spike analysis").
const SpikeSettings kDefaultSpike{};
constexpr std::array<std::pair<SpikeFilter, std::string_view>, 3> kSpikeFilterNames = {{
    {SpikeFilter::Butterworth, "butterworth"},
    {SpikeFilter::Gaussian, "gaussian"},
    {SpikeFilter::None, "none"},
}};

/// The filter of a validated spike.filter string (the registry allows only these names).
SpikeFilter spike_filter_from_text(std::string_view text) {
  for (const auto& [filter, name] : kSpikeFilterNames) {
    if (name == text) return filter;
  }
  throw std::logic_error("spike.filter: unvalidated value '" + std::string(text) + "'");
}

std::vector<std::string> spike_filter_choices() {
  std::vector<std::string> out;
  for (const auto& entry : kSpikeFilterNames) out.emplace_back(entry.second);
  return out;
}

/// The finest resampling of the radial profile: the bilinear pressure has
/// nothing finer than the mesh to show, and the profile (and
/// spike_profiles.csv) grows as 1 / spacing: 1e-7 took 12 GB in 18 s on
/// 65^2, 1e-5 wrote a 2 GB file.
constexpr double kMinResampleMeshes = 0.01;

void add_spike_parameters(std::vector<ParameterSpec>& r) {
  r.push_back(real("output.snapshot_start", kDefaults.snapshot_start, "", at_least(0), kUnbounded,
                   "", "the snapshots every output.snapshot_every steps begin at this time"));
  r.push_back(integer("spike.smoothing_points", kDefaultSpike.smoothing_points, at_least(1),
                      kUnbounded, false,
                      "moving average of the R-sorted P(R) over this many points (paper: 20)"));
  r.push_back(real("spike.max_window_meshes", kDefaultSpike.max_window_meshes, "", above(0),
                   kUnbounded, "",
                   "... spanning at most this many mesh sizes in R (acts near the centre)"));
  r.push_back(choice("spike.filter", spike_filter_text(kDefaultSpike.filter),
                     spike_filter_choices(),
                     "zero-phase low-pass after the average: butterworth (2nd order, forward and "
                     "back), gaussian (ISO 16610-21) or none"));
  r.push_back(real("spike.cutoff_meshes", kDefaultSpike.cutoff_meshes, "", above(0), kUnbounded, "",
                   "cut-off wavelength of the filter in mesh sizes (amplitude 1/2 there); "
                   "> 2 spike.resample_meshes"));
  r.push_back(real("spike.resample_meshes", kDefaultSpike.resample_meshes, "",
                   at_least(kMinResampleMeshes), at_most(1), "",
                   "spacing of the uniform R grid the filter works on, in mesh sizes"));
  r.push_back(real("spike.min_height", kDefaultSpike.min_height, "", at_least(0), at_most(1), "",
                   "the spike is at least this fraction of the largest filtered pressure"));
  r.push_back(real("spike.min_prominence", kDefaultSpike.min_prominence, "", at_least(0),
                   at_most(1), "",
                   "and rises this fraction of it above the lowest point inward of it"));
  r.push_back(real("spike.min_pressure", kDefaultSpike.min_pressure, "", at_least(0), kUnbounded,
                   "",
                   "no spike where the largest pressure of the profile is below this (units of "
                   "the Hertz pressure; the vanishing field before lift-off)"));
}

/// [case]: the dimensionless impact (Moes M, L or lambda_bar, alpha_bar).
void add_case_parameters(std::vector<ParameterSpec>& r) {
  r.push_back(real("case.M", kDefaultM, "", above(0), kUnbounded, "",
                   "Moes load parameter; sets lambda_bar = (128 pi^3 / (3 M^4))^(1/3)"));
  r.push_back(real("case.L", kDefaultL, "", at_least(0), kUnbounded, "",
                   "Moes lubricant parameter; sets alpha_bar = (L / pi) (3 M / 2)^(1/3)"));
  r.push_back(real("case.lambda_bar", kNoDefault, "from case.M", above(0), kUnbounded, "",
                   "12 eta0 R^2 / (a*^2 t_bar ph*); alternative to case.M (not both)"));
  r.push_back(real("case.alpha_bar", kNoDefault, "from case.M and case.L", at_least(0), kUnbounded,
                   "", "alpha ph*; alternative to case.L (not both)"));
}

/// [physical]: the impact in SI units (ball, bodies; the lubricant in
/// add_physical_lubricant_parameters).
void add_physical_case_parameters(std::vector<ParameterSpec>& r) {
  r.push_back(real("physical.reduced_radius", kNoDefault, "none", above(0), kUnbounded, "m",
                   "reduced radius of curvature R (or give physical.ball_radius)"));
  r.push_back(real("physical.ball_radius", kNoDefault, "none", above(0), kUnbounded, "m",
                   "ball radius; a ball on a flat has R = ball radius"));
  r.push_back(real("physical.ball_mass", kNoDefault, "none", above(0), kUnbounded, "kg",
                   "ball mass m (or give physical.ball_density)"));
  r.push_back(real("physical.ball_density", kNoDefault, "none", above(0), kUnbounded, "kg/m^3",
                   "ball density; m = density 4/3 pi R^3"));
  r.push_back(real("physical.impact_speed", kNoDefault, "none", above(0), kUnbounded, "m/s",
                   "approach speed v0"));
  r.push_back(real("physical.reduced_modulus", kNoDefault, "from E1, nu1, E2, nu2", above(0),
                   kUnbounded, "Pa", "reduced modulus E' (or give E1, nu1, E2, nu2)"));
  r.push_back(real("physical.E1", kNoDefault, "none", above(0), kUnbounded, "Pa",
                   "Young's modulus of the ball"));
  r.push_back(real("physical.nu1", kNoDefault, "none", at_least(0), at_most(kPoissonMax), "",
                   "Poisson's ratio of the ball"));
  r.push_back(real("physical.E2", kNoDefault, "none", above(0), kUnbounded, "Pa",
                   "Young's modulus of the flat"));
  r.push_back(real("physical.nu2", kNoDefault, "none", at_least(0), at_most(kPoissonMax), "",
                   "Poisson's ratio of the flat"));
  add_physical_lubricant_parameters(r);
  r.push_back(real("physical.rho0", kNoDefault, "none", above(0), kUnbounded, "kg/m^3",
                   "ambient lubricant density (recorded only: the model uses rho / rho0)"));
}

/// The shortest time step.  kMaxTimeSteps steps of it cover 1e-5 of time,
/// nothing of an impact (its dry contact lasts 3.2181 V0^-0.2); and far below
/// it the discrete equations' 1/dT terms overflow: time.dT = 1e-308 ended
/// with "the multigrid iteration diverged" at step 1, as if the solver had failed.
constexpr double kShortestTimeStep = 1e-12;

/// [time]: step, end, step cap and the start of the ball.
void add_time_parameters(std::vector<ParameterSpec>& r) {
  r.push_back(real("time.dT", kNoDefault, "the mesh size", at_least(kShortestTimeStep), kUnbounded,
                   "",
                   "time step; at most a quarter of an elastic ball's dry contact, 3.2181 "
                   "time.V0^(-1/5) long"));
  {
    ParameterSpec t_end = real("time.T_end", kNoDefault, "until lift-off", above(0), kUnbounded, "",
                               "end time; inf: until lift-off");
    t_end.allow_infinite = true;
    r.push_back(std::move(t_end));
  }
  {
    ParameterSpec cap = integer("time.max_steps", 0, at_least(1), at_most(kMaxTimeSteps), false,
                                "a run until lift-off that has not ended (lift-off or at rest) "
                                "after this many steps fails (exit 1)");
    cap.default_value.reset();
    cap.default_text = "4 dry lift-off times, 4 (Delta0 / V0 + 3.2181 V0^-0.2) / dT";
    r.push_back(std::move(cap));
  }
  r.push_back(real("time.Delta0", kDefaultDelta0, "", above(0), kUnbounded, "",
                   "initial separation Delta(0) (unit: delta*)"));
  r.push_back(real("time.V0", kDefaultV0, "", at_least(kMinV0), at_most(kMaxV0), "",
                   "initial approach speed -dDelta/dT(0) (unit: v0)"));
}

/// [surface]: the waviness of the flat.
void add_surface_parameters(std::vector<ParameterSpec>& r) {
  r.push_back(real("surface.waviness_amplitude", 0.0, "", at_least(0), kUnbounded, "",
                   "amplitude A_w of a cosine waviness added to H (0: smooth)"));
  r.push_back(real("surface.waviness_wavelength", kDefaultWavelength, "", above(0), kUnbounded, "",
                   "wavelength of the waviness; with an amplitude, more than two meshes along the "
                   "wave (else the grid samples another wave)"));
  // One turn either way names every direction; beyond, a huge angle overflowed
  // in its conversion to radians (1e308 deg: a NaN film at amplitude 0).
  r.push_back(real("surface.waviness_angle_deg", 0.0, "", at_least(-kFullTurnDeg),
                   at_most(kFullTurnDeg), "deg",
                   "direction of the waviness wave vector, from the X axis"));
}

/// [output]: snapshots and checkpoints.
void add_output_parameters(std::vector<ParameterSpec>& r) {
  r.push_back(integer("output.snapshot_every", kDefaultSnapshotEvery, at_least(1), kUnbounded,
                      false, "store P and H every this many time steps"));
  r.push_back(real_array("output.snapshot_times", at_least(0),
                         "also store the first step at or after each of these times"));
  r.push_back(integer("output.checkpoint_every", 0, at_least(0), kUnbounded, false,
                      "write checkpoint.nc (for `ehlsim impact --restart`) every this many "
                      "steps; 0: never"));
}

/// [solver]: the shared multigrid keys and the impact's retries, local Newton steps and symmetry.
void add_impact_solver_parameters(std::vector<ParameterSpec>& r) {
  add_solver_parameters(r, kDefaults.solver_settings(),
                        "converged when the scaled finest-grid residual is below this",
                        "multigrid cycles per attempt of a time step (up to twice as many while "
                        "it converges steadily; a stalled step is retried with more damping)");
  r.push_back(real("solver.correction_safeguard", kDefaults.correction_safeguard, "", at_least(0),
                   kUnbounded, "",
                   "in the retries of a step, undo a coarse-grid correction that raises the "
                   "residual norm of its level more than this many times (0: never)"));
  r.push_back(real("solver.retry_damping", kDefaults.retry_damping, "", above(0), below(1), "",
                   "the first retry of a step scales both under-relaxation factors by this, "
                   "each further retry (up to 3) by half as much again"));
  r.push_back(real("solver.force_tolerance", kDefaults.force_tolerance, "", at_least(0), below(1),
                   "",
                   "a step has converged when, besides the residual, its last cycle changed the "
                   "film force by less than this times the largest force so far (0: the "
                   "residual alone)"));
  r.push_back(boolean("solver.contracting_start", kDefaults.contracting_start,
                      fmt::format("where the other starts of a step leave a residual above {:g} "
                                  "times solver.tolerance, also try the series extrapolation in "
                                  "a frame that contracts about the ball's axis with the pressure "
                                  "(the rebound's spike ring), and keep it if its residual is "
                                  "smaller",
                                  kContractingStartTrigger)));
  r.push_back(choice("solver.symmetry", kSymmetryAuto,
                     {std::string(kSymmetryAuto), std::string(kSymmetryOff)},
                     "auto: solve on the quadrant X, Y >= 0 with mirror conditions on the axes "
                     "when the case is even in X and Y (no waviness, or waviness along an axis), "
                     "4 times fewer points; off: always the full domain"));
}

std::vector<ParameterSpec> build_registry() {
  std::vector<ParameterSpec> r;
  add_case_parameters(r);
  add_physical_case_parameters(r);
  add_lubricant_parameters(r);
  add_body_and_grid_points_parameters(r, kDefaultGridPoints);
  r.push_back(real("grid.half_width", kDefaultHalfWidth, "", above(0), kUnbounded, "",
                   "the domain is [-half_width, half_width]^2 (unit: a*); 1.5 is the paper's, "
                   "which takes part of the approach's squeeze film away: on [-3, 3]^2 the "
                   "rebound speed is 2 % lower at M = 100 and 31 % at M = 10 (widen it at the "
                   "same mesh, more points, for the flooded contact; a run warns when the film "
                   "near the edges took more than 1 % of the impact momentum); for an elastic "
                   "ball it must hold the dry contact: > 1.0456 time.V0^(2/5)"));
  add_time_parameters(r);
  add_surface_parameters(r);
  add_output_parameters(r);
  add_impact_solver_parameters(r);
  add_spike_parameters(r);
  return r;
}

}  // namespace

namespace {
const ParameterSet& impact_parameters() {
  static const ParameterSet set{
      {
          {"case", "Moes parameters of the impact (dimensionless case)"},
          {"physical",
           "the case in SI units (ball on a flat), instead of [case]: M, L follow from it"},
          {"lubricant", "viscosity and density laws"},
          {"body", "the solids"},
          {"grid", "the square computational domain"},
          {"time", "time stepping and initial conditions (units: t_bar, delta*)"},
          {"surface", "optional surface waviness"},
          {"output", "what is written to the run directory"},
          {"solver", "multigrid settings"},
          {"spike", "the pressure-spike analysis (spike.csv, ehlsim spike; docs/model.md)"},
      },
      build_registry(),
      "Parameters: in CONFIG.toml write [section] then name = value; on the command line\n"
      "--set section.name=VALUE (VALUE in TOML syntax, a bare word is a string; applied after\n"
      "the file, in order). Defaults give the paper's case M = 100, L = 10 on 257^2 points.\n"};
  return set;
}
}  // namespace

const std::vector<SectionSpec>& parameter_sections() { return impact_parameters().sections; }

const std::vector<ParameterSpec>& parameter_registry() { return impact_parameters().specs; }

const ParameterSpec* find_parameter(std::string_view key) { return impact_parameters().find(key); }

namespace {

/// E' of a [physical] section: physical.reduced_modulus, or E1, nu1, E2, nu2 (not both).
double physical_reduced_modulus(const Inputs& in, const std::string& why) {
  static constexpr std::string_view modulus_keys[] = {"physical.E1", "physical.nu1", "physical.E2",
                                                      "physical.nu2"};
  if (in.has("physical.reduced_modulus")) {
    for (const auto key : modulus_keys) {
      if (in.has(key))
        in.fail(std::string(key),
                "give either physical.reduced_modulus or E1, nu1, E2, nu2, not both");
    }
    return in.real("physical.reduced_modulus");
  }
  const std::string why_modulus = why + " (or give physical.reduced_modulus)";
  const double E1 = in.required_real("physical.E1", why_modulus);
  const double nu1 = in.required_real("physical.nu1", why_modulus);
  const double E2 = in.required_real("physical.E2", why_modulus);
  const double nu2 = in.required_real("physical.nu2", why_modulus);
  return reduced_modulus(E1, nu1, E2, nu2);
}

/// The case of a [physical] section, with its reference scales; the [case]
/// keys are refused beside it.
PhysicalCase physical_case(const Inputs& in) {
  static constexpr std::string_view case_keys[] = {"case.M", "case.L", "case.lambda_bar",
                                                   "case.alpha_bar"};
  for (const auto key : case_keys) {
    if (in.has(key)) {
      in.fail(std::string(key),
              "cannot be combined with a [physical] section (M, L, lambda_bar and alpha_bar are "
              "computed from it)");
    }
  }
  const std::string why = "with a [physical] section";
  const auto exclusive = [&](const std::string& a, const std::string& b) {
    if (in.has(a) && in.has(b)) in.fail(b, fmt::format("give either {} or {}, not both", a, b));
    if (!in.has(a) && !in.has(b)) {
      throw ConfigError(fmt::format("{} (or {}) is required {}", a, b, why), a);
    }
    return in.has(a) ? a : b;
  };
  PhysicalCase p;
  p.reduced_radius_m = in.real(exclusive("physical.ball_radius", "physical.reduced_radius"));
  p.mass_kg = exclusive("physical.ball_mass", "physical.ball_density") == "physical.ball_mass"
                  ? in.real("physical.ball_mass")
                  : sphere_mass(p.reduced_radius_m, in.real("physical.ball_density"));
  p.impact_speed_m_s = in.required_real("physical.impact_speed", why);
  p.reduced_modulus_Pa = physical_reduced_modulus(in, why);
  p.eta0_Pa_s = in.required_real("physical.eta0", why);
  p.alpha_per_Pa = in.required_real("physical.alpha", why);
  p.rho0_kg_m3 = in.optional_real("physical.rho0").value_or(0.0);
  return with_reference_scales(p);
}

/// M, L, lambda_bar and alpha_bar of a [case] section: lambda_bar or M, and
/// alpha_bar or L.
MoesGroups dimensionless_case(const Inputs& in) {
  if (in.has("case.lambda_bar") && in.has("case.M")) {
    in.fail("case.lambda_bar", "cannot be given together with case.M (give one of them)");
  }
  if (in.has("case.alpha_bar") && in.has("case.L")) {
    in.fail("case.alpha_bar", "cannot be given together with case.L (give one of them)");
  }
  MoesGroups g;
  if (const auto lambda_bar = in.optional_real("case.lambda_bar")) {
    g.lambda_bar = *lambda_bar;
    g.M = moes_M(*lambda_bar);
  } else {
    g.M = in.real("case.M");
    g.lambda_bar = moes_lambda_bar(g.M);
  }
  if (const auto alpha_bar = in.optional_real("case.alpha_bar")) {
    g.alpha_bar = *alpha_bar;
    g.L = moes_L(g.lambda_bar, *alpha_bar);
  } else {
    g.L = in.real("case.L");
    g.alpha_bar = moes_alpha_bar(g.M, g.L);
  }
  return g;
}

/// The [case] key that set M (case.M or case.lambda_bar), and the one that set L.
std::string load_key(const Inputs& in) {
  return in.has("case.lambda_bar") ? "case.lambda_bar" : "case.M";
}
std::string lubricant_key(const Inputs& in) {
  return in.has("case.alpha_bar") ? "case.alpha_bar" : "case.L";
}

void assemble_case(const Inputs& in, ImpactConfig& c) {
  c.physical.reset();
  if (in.any_in_section("physical")) c.physical = physical_case(in);
  const MoesGroups g = c.physical ? moes_groups(*c.physical) : dimensionless_case(in);
  check_moes_groups(in, g, load_key(in), lubricant_key(in));
  c.M = g.M;
  c.L = g.L;
  c.lambda_bar = g.lambda_bar;
  c.alpha_bar = g.alpha_bar;
}

void assemble_impact_lubricant(const Inputs& in, ImpactConfig& c) {
  std::optional<PhysicalLubricant> physical;
  if (c.physical)
    physical = {c.physical->ph_star_Pa, c.physical->eta0_Pa_s, c.physical->alpha_per_Pa};
  c.lubricant = assemble_lubricant(in, c.alpha_bar, physical);
  const MoesGroups g = with_lubricant_L(in, c.lubricant, {c.M, c.L, c.lambda_bar, c.alpha_bar},
                                        {"case.L", "case.alpha_bar"}, load_key(in));
  c.L = g.L;
  c.alpha_bar = g.alpha_bar;
  c.lubricant.alpha_bar = g.alpha_bar;
}

/// The waviness amplitude below which the undeformed gap of `c` at T = 0 is
/// positive at every grid point (infinite without waviness).
double largest_waviness_amplitude(const ImpactConfig& c) {
  double largest = std::numeric_limits<double>::infinity();
  if (!(c.waviness_amplitude > 0.0)) return largest;
  const Grid2D grid(c.grid_points, c.half_width);
  for (int j = 0; j < grid.n; ++j) {
    for (int i = 0; i < grid.n; ++i) {
      const double x = grid.x(i), y = grid.y(j);
      const double wave = waviness_height(c, x, y) / c.waviness_amplitude;  // cos(...)
      if (wave < 0.0) largest = std::min(largest, (c.Delta0 + 0.5 * (x * x + y * y)) / -wave);
    }
  }
  return largest;
}

/// The undeformed gap at T = 0, Delta0 + (X^2 + Y^2) / 2 + waviness, must be
/// positive at every grid point: a start with the surfaces already through
/// each other is no impact (model.md).  Only the waviness can make it negative.
void check_undeformed_gap(const Inputs& in, const ImpactConfig& c) {
  const double largest = largest_waviness_amplitude(c);
  if (c.waviness_amplitude < largest) return;
  in.fail("surface.waviness_amplitude",
          fmt::format("must be < {:.6g} for time.Delta0 = {:g} on this grid (the undeformed gap "
                      "Delta0 + (X^2 + Y^2)/2 + A_w cos(...) at T = 0 must be > 0 at every grid "
                      "point)",
                      largest, c.Delta0));
}

/// A waviness the grid samples as another wave is no input the user meant:
/// its wave vector must lie below the grid's Nyquist limit pi / h along X
/// and along Y, so the wavelength must exceed 2 h max(|cos|, |sin|) of
/// surface.waviness_angle_deg.
void check_waviness_resolved(const Inputs& in, const ImpactConfig& c) {
  if (!(c.waviness_amplitude > 0.0)) return;
  const double angle = c.waviness_angle_deg * std::numbers::pi / 180.0;
  const double shortest = 2.0 * Grid2D(c.grid_points, c.half_width).h() *
                          std::max(std::abs(std::cos(angle)), std::abs(std::sin(angle)));
  if (c.waviness_wavelength > shortest) return;
  in.fail("surface.waviness_wavelength",
          fmt::format("must be > {:.4g} on this grid (two meshes along the wave, the shortest "
                      "wave the grid does not sample as another one)",
                      shortest));
}

/// The fewest time steps the dry contact may span.  With fewer the contact
/// is not resolved in time: on 33^2 and 65^2 (the default case) time.dT = 1.5
/// to 3 (1.1 to 2.1 steps per contact) ended with exit 0 after 2 to 4 steps,
/// one with a rebound speed above V0; time.dT = 0.8 to 1.2 (2.7 to 4)
/// ended with a negative film, 0.7 (4.6) lifted off at 0.83 V0 (0.92 on fine
/// grids).
constexpr double kMinStepsPerDryContact = 4.0;

/// The key to name for a mesh that fails a check: the one the user gave.
std::string mesh_key(const Inputs& in) {
  return in.has("grid.half_width") ? "grid.half_width" : "grid.points";
}

/// The grid must resolve the film's pressure zone: the squeeze film at the
/// start, about sqrt(2 Delta0) wide (the gap doubles there), or an elastic
/// ball's dry contact (its largest radius), the wider of the two.  With a mesh
/// wider than both nothing is resolved: grid.half_width = 1e300 (time.dT =
/// 0.01) ended at T = 0 as a film "too viscous"; V0 = Delta0 = 1e-3 on 33^2
/// (mesh 0.094, zones 0.045 and 0.066) rebounded at 3.0 V0, on 65^2 and 129^2
/// at 3.6 and 3.7 V0.
void check_mesh_resolves_the_film(const Inputs& in, const ImpactConfig& c) {
  const double film = std::sqrt(2.0 * c.Delta0);
  const double contact = c.elastic ? dry_largest_contact_radius(c.V0) : 0.0;
  const double mesh = Grid2D(c.grid_points, c.half_width).h();
  if (mesh < std::max(film, contact)) return;
  const std::string zones =
      c.elastic ? fmt::format(
                      "the wider of the squeeze film at the start, sqrt(2 time.Delta0) = "
                      "{:.4g}, and the largest radius of the dry contact at time.V0 = "
                      "{:g}, {:.4g}",
                      film, c.V0, contact)
                : fmt::format(
                      "the width of the squeeze film at the start, sqrt(2 time.Delta0) "
                      "= {:.4g}",
                      film);
  in.fail(mesh_key(in),
          fmt::format("gives a mesh of {:.4g}, not below {}: the grid cannot resolve the film; "
                      "use more points or a smaller domain",
                      mesh, zones));
}

/// An elastic ball's dry contact must fit into the domain, and its duration
/// must span kMinStepsPerDryContact time steps: else the run can only fail
/// or give a result of the discretisation (model.md, "Reference values").  A
/// rigid ball has no dry contact.
void check_dry_contact_resolved(const Inputs& in, const ImpactConfig& c) {
  if (!c.elastic) return;
  const double radius = dry_largest_contact_radius(c.V0);
  if (!(c.half_width > radius)) {
    in.fail("grid.half_width",
            fmt::format("must be > {:.4g}, the largest radius of the dry contact at time.V0 = "
                        "{:g}: the domain must hold the contact (the paper's is 1.5)",
                        radius, c.V0));
  }
  const double duration = dry_contact_duration(c.V0);
  const double largest_dT = duration / kMinStepsPerDryContact;
  const double dT = effective_time_step(c);
  if (dT <= largest_dT) return;
  const std::string why = fmt::format(
      "the dry contact at time.V0 = {:g} lasts {:.4g}, and a run needs at least {:g} steps in it",
      c.V0, duration, kMinStepsPerDryContact);
  if (in.has("time.dT")) in.fail("time.dT", fmt::format("must be <= {:.4g}: {}", largest_dT, why));
  in.fail(mesh_key(in),
          fmt::format("gives a mesh, and so a default time.dT, of {:.4g}; it must be <= {:.4g} "
                      "({}): set time.dT or use a finer mesh",
                      dT, largest_dT, why));
}

/// The mesh that gives the default time.dT must not be shorter than that.
void check_time_step_not_negligible(const Inputs& in, const ImpactConfig& c) {
  const double dT = effective_time_step(c);
  if (dT >= kShortestTimeStep) return;  // a time.dT given is checked by its range
  in.fail(mesh_key(in),
          fmt::format("gives a mesh, and so a default time.dT, of {:.4g}; it must be >= {:g}: "
                      "set time.dT or use a coarser mesh",
                      dT, kShortestTimeStep));
}

/// `x` rounded to three significant digits, up or down: the value a message
/// shows must itself pass the check it suggests.
double three_digits(double x, bool up) {
  const double unit = std::pow(10.0, std::floor(std::log10(x)) - 2.0);
  return (up ? std::ceil(x / unit) : std::floor(x / unit)) * unit;
}

/// The key of `in` to name for a step count that one of the fixes found changes.
std::string step_cap_key(const Inputs& in, bool longer_step, bool closer) {
  if (longer_step && in.has("time.dT")) return "time.dT";
  if (closer && in.has("time.Delta0")) return "time.Delta0";
  if (closer && in.has("time.V0")) return "time.V0";
  if (longer_step && (in.has("grid.half_width") || in.has("grid.points"))) return mesh_key(in);
  for (const char* key : {"time.Delta0", "time.V0", "time.dT", "grid.half_width", "grid.points"})
    if (in.has(key)) return key;
  return "time.Delta0";
}

/// Whether the other checks let `c` start at `Delta0`: the grid resolves the
/// film from there (check_mesh_resolves_the_film), and the waviness leaves
/// the undeformed gap positive (check_undeformed_gap).
bool may_start_at(const ImpactConfig& c, double Delta0) {
  ImpactConfig closer = c;
  closer.Delta0 = Delta0;
  const double mesh = Grid2D(c.grid_points, c.half_width).h();
  const double zone =
      std::max(std::sqrt(2.0 * Delta0), c.elastic ? dry_largest_contact_radius(c.V0) : 0.0);
  return mesh < zone && c.waviness_amplitude < largest_waviness_amplitude(closer);
}

/// The furthest start from which a run of `c` until lift-off with steps of
/// `dT` stays within kMaxTimeSteps (rounded down), or 0 where the contact
/// alone needs more: the steps of the contact stay, those of the flight
/// before it grow with Delta0.
double closest_start(const ImpactConfig& c, double dT) {
  const double limit = kMaxTimeSteps;
  const double steps = default_max_steps_exact(c.Delta0, c.V0, dT);
  const double contact_steps = default_max_steps_exact(0.0, c.V0, dT);
  if (!(contact_steps < limit)) return 0.0;
  return three_digits(c.Delta0 * (limit - contact_steps) / (steps - contact_steps), false);
}

/// A run until lift-off whose default step cap exceeds kMaxTimeSteps: the
/// message says what would fit (a longer time step, within a quarter of the
/// dry contact; a closer start the grid resolves), and names the key the user gave that one
/// of them changes.  It blamed time.dT where no allowed dT would do, and
/// time.V0 = 1 (the default) for a start far away; and its values must pass
/// when applied.
void check_default_step_cap(const Inputs& in, const ImpactConfig& c) {
  const double dT = effective_time_step(c);
  const double limit = kMaxTimeSteps;
  const double steps = default_max_steps_exact(c.Delta0, c.V0, dT);
  if (steps <= limit) return;
  const double longest = c.elastic ? dry_contact_duration(c.V0) / kMinStepsPerDryContact
                                   : std::numeric_limits<double>::infinity();
  std::vector<std::string> fixes;
  const double needed_dT = three_digits(steps / limit * dT, true);
  const bool longer_step = needed_dT <= longest;
  if (longer_step) fixes.push_back(fmt::format("a time.dT of {:g} or more", needed_dT));
  const double closest = closest_start(c, dT);
  const bool closer = closest > 0.0 && may_start_at(c, closest);
  if (closer) fixes.push_back(fmt::format("a time.Delta0 of {:g} or less", closest));
  if (fixes.empty() && std::isfinite(longest)) {
    // Both together, where the closest start the longest step allows may be taken.
    const double step = three_digits(longest, false);
    const double start = closest_start(c, step);
    if (start > 0.0 && may_start_at(c, start))
      fixes.push_back(
          fmt::format("a time.Delta0 of {:g} or less with a time.dT of {:g}", start, step));
  }
  fixes.emplace_back("time.T_end or time.max_steps");
  in.fail(step_cap_key(in, longer_step, closer),
          fmt::format("a run until lift-off from time.Delta0 = {:g} at time.V0 = {:g} with "
                      "time steps of dT = {:.4g} may need {:.3g} time steps (the default "
                      "time.max_steps, 4 (Delta0 / V0 + 3.2181 V0^-0.2) / dT); at most {} "
                      "are allowed: set {}",
                      c.Delta0, c.V0, dT, steps, kMaxTimeSteps, fmt::join(fixes, ", or ")));
}

/// A run of more than kMaxTimeSteps steps is refused before it starts: a
/// start far away or slow needs billions of steps (and an int overflows).
/// The message names time.dT where the user gave it, else the end or the start.
void check_step_count(const Inputs& in, const ImpactConfig& c) {
  const double dT = effective_time_step(c);
  const double limit = kMaxTimeSteps;
  const bool dT_given = in.has("time.dT");
  if (std::isfinite(c.T_end)) {
    const double steps = std::ceil(c.T_end / dT);
    if (steps <= limit) return;
    if (dT_given)
      in.fail("time.dT", fmt::format("needs {:.3g} time steps to time.T_end = {:g}; at most {} are "
                                     "allowed: use a longer time.dT or an earlier time.T_end",
                                     steps, c.T_end, kMaxTimeSteps));
    in.fail("time.T_end",
            fmt::format("needs {:.3g} time steps of time.dT = {:.4g}; at most {} are allowed",
                        steps, dT, kMaxTimeSteps));
  }
  if (in.has("time.max_steps")) return;  // within the registry's range
  check_default_step_cap(in, c);
}

/// solver.coarse_face_mean = "auto" for an impact: the logarithmic mean from
/// L = 20 on, where the spike is sharp enough that the coarse levels'
/// arithmetic mean overstates its flux many times; below, the finest grid's
/// mean (at L = 10 the logarithmic one cost 13 % more on 513^2).  Work per
/// step, logarithmic against arithmetic: L = 20 on 65^2 to 513^2 0.84-1.01,
/// 1025^2 about half the time; L = 15 1.04 and 0.91 (docs/performance.md,
/// "The coarse levels' face mean").
constexpr double kLogarithmicCoarseFromL = 20.0;

std::optional<FaceMean> auto_coarse_face_mean(double L) {
  return L >= kLogarithmicCoarseFromL ? std::optional(FaceMean::Logarithmic) : std::nullopt;
}

void assemble_rest(const Inputs& in, ImpactConfig& c) {
  c.elastic = in.get<bool>("body.elastic");
  c.grid_points = in.integer("grid.points");
  c.half_width = in.real("grid.half_width");
  c.dT = in.optional_real("time.dT").value_or(0.0);
  c.T_end = in.optional_real("time.T_end").value_or(std::numeric_limits<double>::infinity());
  c.Delta0 = in.real("time.Delta0");
  c.V0 = in.real("time.V0");
  c.max_steps = in.has("time.max_steps")
                    ? in.get<int>("time.max_steps")
                    : default_max_steps(c.Delta0, c.V0, effective_time_step(c));
  c.waviness_amplitude = in.real("surface.waviness_amplitude");
  c.waviness_wavelength = in.real("surface.waviness_wavelength");
  c.waviness_angle_deg = in.real("surface.waviness_angle_deg");
  c.snapshot_every = in.integer("output.snapshot_every");
  c.snapshot_times = in.get<std::vector<double>>("output.snapshot_times");
  c.checkpoint_every = in.integer("output.checkpoint_every");
  static_cast<SolverSettings&>(c) = assemble_solver(in, auto_coarse_face_mean(c.L));
  c.correction_safeguard = in.real("solver.correction_safeguard");
  c.retry_damping = in.real("solver.retry_damping");
  c.force_tolerance = in.real("solver.force_tolerance");
  c.contracting_start = in.get<bool>("solver.contracting_start");
  c.use_symmetry = in.get<std::string>("solver.symmetry") == kSymmetryAuto;
  check_waviness_resolved(in, c);
  check_undeformed_gap(in, c);
  check_dry_contact_resolved(in, c);
  check_mesh_resolves_the_film(in, c);
  check_time_step_not_negligible(in, c);
  check_step_count(in, c);
}

void assemble_spike(const Inputs& in, ImpactConfig& c) {
  c.snapshot_start = in.real("output.snapshot_start");
  SpikeSettings& s = c.spike;
  s.smoothing_points = in.integer("spike.smoothing_points");
  s.max_window_meshes = in.real("spike.max_window_meshes");
  s.filter = spike_filter_from_text(in.get<std::string>("spike.filter"));
  s.cutoff_meshes = in.real("spike.cutoff_meshes");
  s.resample_meshes = in.real("spike.resample_meshes");
  s.min_height = in.real("spike.min_height");
  s.min_prominence = in.real("spike.min_prominence");
  s.min_pressure = in.real("spike.min_pressure");
  if (s.filter != SpikeFilter::None && !(s.cutoff_meshes > 2.0 * s.resample_meshes)) {
    in.fail("spike.cutoff_meshes",
            fmt::format("must be > 2 spike.resample_meshes = {:g} (the shortest wave the "
                        "resampled profile carries)",
                        2.0 * s.resample_meshes));
  }
}

}  // namespace

ImpactConfig load_config(const std::optional<std::filesystem::path>& file,
                         const std::vector<std::string>& overrides, std::string_view origin) {
  const Inputs inputs = read_inputs(impact_parameters(), file, overrides, origin);
  ImpactConfig config;
  assemble_case(inputs, config);
  assemble_impact_lubricant(inputs, config);
  assemble_rest(inputs, config);
  assemble_spike(inputs, config);
  return config;
}

// ---------------------------------------------------------------------------
// Help and echo
// ---------------------------------------------------------------------------

std::string describe_parameters() { return describe_parameters(impact_parameters()); }

std::string_view spike_filter_text(SpikeFilter filter) {
  for (const auto& [value, name] : kSpikeFilterNames) {
    if (value == filter) return name;
  }
  throw std::logic_error("spike_filter_text: unknown filter");
}

nlohmann::json effective_parameters_json(const ImpactConfig& c) {
  using nlohmann::json;
  json j;
  j["case"] = {{"M", c.M}, {"L", c.L}, {"lambda_bar", c.lambda_bar}, {"alpha_bar", c.alpha_bar}};
  if (c.physical) {
    const PhysicalCase& p = *c.physical;
    j["physical"] = {{"reduced_radius", p.reduced_radius_m},
                     {"ball_mass", p.mass_kg},
                     {"impact_speed", p.impact_speed_m_s},
                     {"reduced_modulus", p.reduced_modulus_Pa},
                     {"eta0", p.eta0_Pa_s},
                     {"alpha", p.alpha_per_Pa}};
    if (p.rho0_kg_m3 > 0.0) j["physical"]["rho0"] = p.rho0_kg_m3;
    j["scales"] = {{"delta_star_m", p.delta_star_m},
                   {"a_star_m", p.a_star_m},
                   {"ph_star_Pa", p.ph_star_Pa},
                   {"F_star_N", p.F_star_N},
                   {"t_bar_s", p.t_bar_s}};
  }
  j["lubricant"] = lubricant_json(c.lubricant);
  j["body"] = {{"elastic", c.elastic}};
  j["grid"] = {{"points", c.grid_points}, {"half_width", c.half_width}};
  j["time"] = {{"dT", effective_time_step(c)},
               {"T_end", std::isfinite(c.T_end) ? json(c.T_end) : json(nullptr)},
               {"max_steps", c.max_steps},
               {"Delta0", c.Delta0},
               {"V0", c.V0}};
  j["surface"] = {{"waviness_amplitude", c.waviness_amplitude},
                  {"waviness_wavelength", c.waviness_wavelength},
                  {"waviness_angle_deg", c.waviness_angle_deg}};
  j["output"] = {{"snapshot_every", c.snapshot_every},
                 {"snapshot_times", c.snapshot_times},
                 {"checkpoint_every", c.checkpoint_every}};
  j["solver"] = solver_settings_json(c);
  j["solver"]["correction_safeguard"] = c.correction_safeguard;
  j["solver"]["retry_damping"] = c.retry_damping;
  j["solver"]["force_tolerance"] = c.force_tolerance;
  j["solver"]["contracting_start"] = c.contracting_start;
  j["solver"]["symmetry"] = c.use_symmetry ? kSymmetryAuto : kSymmetryOff;
  j["output"]["snapshot_start"] = c.snapshot_start;
  j["spike"] = {{"smoothing_points", c.spike.smoothing_points},
                {"max_window_meshes", c.spike.max_window_meshes},
                {"filter", spike_filter_text(c.spike.filter)},
                {"cutoff_meshes", c.spike.cutoff_meshes},
                {"resample_meshes", c.spike.resample_meshes},
                {"min_height", c.spike.min_height},
                {"min_prominence", c.spike.min_prominence},
                {"min_pressure", c.spike.min_pressure}};
  return j;
}

}  // namespace ehlsim
