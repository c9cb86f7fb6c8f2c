#include "config/Parameters.hpp"

#include <fmt/format.h>
#include <toml++/toml.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <numbers>
#include <sstream>
#include <system_error>
#include <utility>

#include "config/ParameterSet.hpp"
#include "dynamics/DryHertz.hpp"
#include "grid/Grid.hpp"
#include "grid/NumberText.hpp"
#include "impact/RunGuards.hpp"
#include "impact/Scaling.hpp"
#include "rheology/Lubricant.hpp"

namespace ehlsim {

ConfigError::ConfigError(const std::string& message, std::string key)
    : std::runtime_error(message), key_(std::move(key)) {}

std::string echo_input(std::string_view text) {
  if (text.size() <= kEchoMaxChars) return std::string(text);
  std::size_t cut = kEchoMaxChars;
  // Not inside a UTF-8 sequence: continuation bytes are 10xxxxxx.
  constexpr unsigned char kContinuationMask = 0xC0, kContinuation = 0x80;
  while (cut > 0 && (static_cast<unsigned char>(text[cut]) & kContinuationMask) == kContinuation)
    --cut;
  return fmt::format("{}... ({} bytes)", text.substr(0, cut), text.size());
}

// ---------------------------------------------------------------------------
// Enumerations <-> TOML strings
// ---------------------------------------------------------------------------

namespace {
constexpr std::string_view kBarus = "barus";
constexpr std::string_view kRoelands = "roelands";
constexpr std::string_view kIncompressible = "incompressible";
constexpr std::string_view kDowsonHigginson = "dowson-higginson";
constexpr std::string_view kCycleV = "V";
constexpr std::string_view kCycleW = "W";
constexpr std::string_view kFft = "fft";
constexpr std::string_view kDirect = "direct";

/// The largest config file read: a case is a few hundred bytes, a long
/// output.snapshot_times list some kB; a runaway value of 10 MB is still read
/// (to be refused with its key named, shortened).
constexpr std::size_t kMaxConfigBytes = std::size_t{16} << 20;
}  // namespace

std::string_view viscosity_model_text(ViscosityModel model) {
  return model == ViscosityModel::Roelands ? kRoelands : kBarus;
}
std::string_view density_model_text(DensityModel model) {
  return model == DensityModel::DowsonHigginson ? kDowsonHigginson : kIncompressible;
}
std::string_view cycle_type_text(CycleType cycle) {
  return cycle == CycleType::W ? kCycleW : kCycleV;
}
std::string_view deformation_method_text(DeformationMethod method) {
  return method == DeformationMethod::Direct ? kDirect : kFft;
}

// ---------------------------------------------------------------------------
// The registry
// ---------------------------------------------------------------------------

Bound above(double v) { return {v, false}; }
Bound at_least(double v) { return {v, true}; }
Bound at_most(double v) { return {v, true}; }
Bound below(double v) { return {v, false}; }

ParameterSpec real(std::string key, std::optional<double> def, std::string default_text,
                   std::optional<Bound> lower, std::optional<Bound> upper, std::string units,
                   std::string doc) {
  ParameterSpec s;
  s.key = std::move(key);
  s.type = ParameterType::Float;
  if (def) s.default_value = *def;
  s.default_text = std::move(default_text);
  s.lower = lower;
  s.upper = upper;
  s.units = std::move(units);
  s.doc = std::move(doc);
  return s;
}

ParameterSpec integer(std::string key, int def, std::optional<Bound> lower,
                      std::optional<Bound> upper, bool power_of_two_plus_one, std::string doc) {
  ParameterSpec s;
  s.key = std::move(key);
  s.type = ParameterType::Int;
  s.default_value = def;
  s.lower = lower;
  s.upper = upper;
  s.power_of_two_plus_one = power_of_two_plus_one;
  s.doc = std::move(doc);
  return s;
}

ParameterSpec boolean(std::string key, bool def, std::string doc) {
  ParameterSpec s;
  s.key = std::move(key);
  s.type = ParameterType::Bool;
  s.default_value = def;
  s.doc = std::move(doc);
  return s;
}

ParameterSpec choice(std::string key, std::string_view def, std::vector<std::string> choices,
                     std::string doc) {
  ParameterSpec s;
  s.key = std::move(key);
  s.type = ParameterType::Enum;
  s.default_value = std::string(def);
  s.choices = std::move(choices);
  s.doc = std::move(doc);
  return s;
}

ParameterSpec real_array(std::string key, std::optional<Bound> lower, std::string doc) {
  ParameterSpec s;
  s.key = std::move(key);
  s.type = ParameterType::FloatArray;
  s.default_value = std::vector<double>{};
  s.lower = lower;
  s.doc = std::move(doc);
  return s;
}

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
const int kDefaultSnapshotEvery = kDefaults.snapshot_every;
constexpr std::string_view kArithmetic = "arithmetic";
constexpr std::string_view kHarmonic = "harmonic";
constexpr std::string_view kLogarithmic = "logarithmic";
constexpr std::string_view kLinesAlternating = "alternating";
constexpr std::string_view kLinesX = "x";
constexpr std::string_view kUpdatesPerSweep = "sweep";
constexpr std::string_view kUpdatesPerColour = "colour";
constexpr std::string_view kSymmetryAuto = "auto";
constexpr std::string_view kSymmetryOff = "off";
/// solver.local_newton: a half-width w gives a dense system of up to
/// (2w + 1)^2 unknowns per cycle; at 20 that is 1681, 23 MB and about 3e9
/// operations for its LU factors, more than a cycle of a 1025^2 grid.
constexpr int kMaxLocalNewtonHalfWidth = 20;
/// solver.local_newton_windows: a bound that keeps a typo from asking for a
/// dense solve around every point; 1000 windows of the default half-width
/// cover 169 000 points, two thirds of the quadrant of 1025^2.
constexpr int kMaxLocalNewtonWindows = 1000;

FaceMean face_mean_from_text(std::string_view text) {
  if (text == kHarmonic) return FaceMean::Harmonic;
  if (text == kLogarithmic) return FaceMean::Logarithmic;
  return FaceMean::Arithmetic;
}
std::string_view face_mean_text(FaceMean mean) {
  switch (mean) {
    case FaceMean::Harmonic:
      return kHarmonic;
    case FaceMean::Logarithmic:
      return kLogarithmic;
    case FaceMean::Arithmetic:
      break;
  }
  return kArithmetic;
}

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

/// [time]: step, end, step cap and the start of the ball.
void add_time_parameters(std::vector<ParameterSpec>& r) {
  r.push_back(real("time.dT", kNoDefault, "the mesh size", above(0), kUnbounded, "",
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
  r.push_back(real("surface.waviness_angle_deg", 0.0, "", kUnbounded, kUnbounded, "deg",
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

std::string format_number(double v) { return fmt::format("{:g}", v); }

std::string quoted_list(const std::vector<std::string>& items) {
  std::string out;
  for (const auto& item : items) {
    if (!out.empty()) out += ", ";
    out += '"' + item + '"';
  }
  return out;
}

/// "> 0", ">= 0", "< 1", "in [0, 0.5]", "" for a plain interval.
std::string interval_text(const std::optional<Bound>& lower, const std::optional<Bound>& upper) {
  if (lower && upper) {
    return fmt::format("in {}{}, {}{}", lower->inclusive ? "[" : "(", format_number(lower->value),
                       format_number(upper->value), upper->inclusive ? "]" : ")");
  }
  if (lower)
    return fmt::format("{} {}", lower->inclusive ? ">=" : ">", format_number(lower->value));
  if (upper)
    return fmt::format("{} {}", upper->inclusive ? "<=" : "<", format_number(upper->value));
  return {};
}

bool in_interval(const std::optional<Bound>& lower, const std::optional<Bound>& upper, double v) {
  if (std::isnan(v)) return false;
  if (lower && !(lower->inclusive ? v >= lower->value : v > lower->value)) return false;
  if (upper && !(upper->inclusive ? v <= upper->value : v < upper->value)) return false;
  return true;
}

}  // namespace

std::string_view ParameterSpec::section() const {
  const std::string_view k = key;
  return k.substr(0, k.find('.'));
}

std::string_view ParameterSpec::name() const {
  const std::string_view k = key;
  return k.substr(k.find('.') + 1);
}

std::string ParameterSpec::allowed() const {
  switch (type) {
    case ParameterType::Bool:
      return "true or false";
    case ParameterType::Enum:
      return "one of " + quoted_list(choices);
    case ParameterType::FloatArray: {
      const std::string range = interval_text(lower, upper);
      return range.empty() ? "an array of numbers" : "an array of numbers " + range;
    }
    case ParameterType::Int: {
      if (power_of_two_plus_one && lower && upper) {
        return fmt::format("2^k + 1 between {} and {}", format_number(lower->value),
                           format_number(upper->value));
      }
      const std::string range = interval_text(lower, upper);
      return range.empty() ? "an integer" : range;
    }
    case ParameterType::Float: {
      const std::string range = interval_text(lower, upper);
      return range.empty() ? "a finite number" : range;
    }
  }
  return {};
}

std::string ParameterSpec::default_description() const {
  if (!default_value) return default_text.empty() ? "none" : default_text;
  return std::visit(
      [](const auto& v) -> std::string {
        using T = std::decay_t<decltype(v)>;
        if constexpr (std::is_same_v<T, bool>) {
          return v ? "true" : "false";
        } else if constexpr (std::is_same_v<T, int>) {
          return std::to_string(v);
        } else if constexpr (std::is_same_v<T, double>) {
          return format_number(v);
        } else if constexpr (std::is_same_v<T, std::string>) {
          return '"' + v + '"';
        } else {
          std::string out = "[";
          for (std::size_t i = 0; i < v.size(); ++i) out += (i ? ", " : "") + format_number(v[i]);
          return out + "]";
        }
      },
      *default_value);
}

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

const ParameterSpec* ParameterSet::find(std::string_view key) const {
  const auto it = std::find_if(specs.begin(), specs.end(),
                               [&](const ParameterSpec& s) { return s.key == key; });
  return it == specs.end() ? nullptr : &*it;
}

// ---------------------------------------------------------------------------
// Reading: TOML tree -> validated values
// ---------------------------------------------------------------------------

namespace {

bool is_known_section(const ParameterSet& set, std::string_view name) {
  const auto& sections = set.sections;
  return std::any_of(sections.begin(), sections.end(),
                     [&](const SectionSpec& s) { return s.name == name; });
}

std::string section_list(const ParameterSet& set) {
  std::string out;
  for (const auto& s : set.sections) out += (out.empty() ? "" : ", ") + s.name;
  return out;
}

std::string keys_in_section(const ParameterSet& set, std::string_view section) {
  std::string out;
  for (const auto& s : set.specs) {
    if (s.section() == section) out += (out.empty() ? "" : ", ") + std::string(s.name());
  }
  return out;
}

/// A value as the user wrote it, for messages (TOML-like syntax).
std::string node_text(const toml::node& node) {
  if (node.is_table()) return "{...}";
  if (const auto* v = node.as_boolean()) return v->get() ? "true" : "false";
  if (const auto* v = node.as_integer()) return std::to_string(v->get());
  if (const auto* v = node.as_floating_point()) return fmt::format("{}", v->get());
  if (const auto* v = node.as_string()) return '"' + v->get() + '"';
  if (const auto* a = node.as_array()) {
    std::string out = "[";
    for (std::size_t i = 0; i < a->size(); ++i) out += (i ? ", " : "") + node_text(*a->get(i));
    return out + "]";
  }
  std::ostringstream os;
  node.visit([&](const auto& v) {
    if constexpr (!toml::is_table<decltype(v)>) os << v;
  });
  return os.str();
}

/// Where a value came from: "file.toml:LINE:COL" for a node of the config
/// file `file` ("" when there is none), else the origin its override was
/// parsed with ("--set", or a file the overrides were taken from).
std::string node_origin(const toml::node& node, std::string_view file) {
  const toml::source_region& src = node.source();
  if (!src.path) return std::string(kOverrideOrigin);
  if (!file.empty() && *src.path == file) {
    return fmt::format("{}:{}:{}", *src.path, src.begin.line, src.begin.column);
  }
  return *src.path;
}

std::string origin_suffix(const std::string& origin) {
  return origin.empty() ? std::string() : " (" + origin + ")";
}

[[noreturn]] void fail_value(const std::string& key, const std::string& text,
                             const std::string& problem, const std::string& origin) {
  throw ConfigError(fmt::format("{} = {}: {}{}", echo_input(key), echo_input(text), problem,
                                origin_suffix(origin)),
                    key);
}

std::optional<double> number_of(const toml::node& node) {
  if (const auto* v = node.as_integer()) return static_cast<double>(v->get());
  if (const auto* v = node.as_floating_point()) return v->get();
  return std::nullopt;
}

std::string with_space(const std::string& s) { return s.empty() ? s : " " + s; }

/// Throws the one-line error of a given value: key, value as written, what is
/// allowed, and where it was given.
struct ValueProblem {
  const ParameterSpec& spec;
  const Given& given;
  [[noreturn]] void operator()(const std::string& problem) const {
    fail_value(spec.key, given.text, problem, given.origin);
  }
};

ParameterValue convert_enum(const ParameterSpec& spec, const toml::node& node,
                            const ValueProblem& fail) {
  const auto* v = node.as_string();
  if (!v || std::find(spec.choices.begin(), spec.choices.end(), v->get()) == spec.choices.end()) {
    fail("must be " + spec.allowed());
  }
  return v->get();
}

ParameterValue convert_float(const ParameterSpec& spec, const toml::node& node,
                             const ValueProblem& fail) {
  const std::string range = interval_text(spec.lower, spec.upper);
  const std::optional<double> v = number_of(node);
  if (!v || std::isnan(*v)) fail("must be a number" + with_space(range));
  if (std::isinf(*v) && !(spec.allow_infinite && *v > 0)) {
    fail("must be a finite number" + with_space(range));
  }
  if (!in_interval(spec.lower, spec.upper, *v)) fail("must be " + range);
  return *v;
}

ParameterValue convert_int(const ParameterSpec& spec, const toml::node& node,
                           const ValueProblem& fail) {
  std::optional<double> v;
  if (const auto* i = node.as_integer()) {
    v = static_cast<double>(i->get());
  } else if (const auto* f = node.as_floating_point();
             f && std::isfinite(f->get()) && std::trunc(f->get()) == f->get()) {
    v = f->get();  // an integral float such as 257.0
  }
  if (!v) {
    const std::string allowed = spec.allowed();
    fail(allowed == "an integer" ? "must be an integer" : "must be an integer " + allowed);
  }
  const bool fits = *v >= static_cast<double>(std::numeric_limits<int>::min()) &&
                    *v <= static_cast<double>(std::numeric_limits<int>::max());
  if (!fits) fail("is too large (must fit in a 32-bit integer)");
  const bool ok = in_interval(spec.lower, spec.upper, *v) &&
                  (!spec.power_of_two_plus_one || is_power_of_two_plus_one(static_cast<long>(*v)));
  if (!ok) fail("must be " + spec.allowed());
  return static_cast<int>(*v);
}

ParameterValue convert_float_array(const ParameterSpec& spec, const toml::node& node,
                                   const ValueProblem& fail) {
  std::vector<double> values;
  if (const std::optional<double> single = number_of(node)) {
    values.push_back(*single);  // a single number is a one-entry array
  } else if (const auto* a = node.as_array()) {
    for (const auto& element : *a) {
      const std::optional<double> v = number_of(element);
      if (!v) fail("must be " + spec.allowed());
      values.push_back(*v);
    }
  } else {
    fail("must be " + spec.allowed());
  }
  const std::string range = interval_text(spec.lower, spec.upper);
  for (const double v : values) {
    if (!std::isfinite(v)) fail("every entry must be a finite number" + with_space(range));
    if (!in_interval(spec.lower, spec.upper, v)) fail("every entry must be " + range);
  }
  return values;
}

Given convert(const ParameterSpec& spec, const toml::node& node, std::string_view file) {
  Given g;
  g.text = node_text(node);
  g.origin = node_origin(node, file);
  const ValueProblem fail{spec, g};
  switch (spec.type) {
    case ParameterType::Bool: {
      const auto* v = node.as_boolean();
      if (!v) fail("must be true or false");
      g.value = v->get();
      break;
    }
    case ParameterType::Enum:
      g.value = convert_enum(spec, node, fail);
      break;
    case ParameterType::Float:
      g.value = convert_float(spec, node, fail);
      break;
    case ParameterType::Int:
      g.value = convert_int(spec, node, fail);
      break;
    case ParameterType::FloatArray:
      g.value = convert_float_array(spec, node, fail);
      break;
  }
  return g;
}

std::string read_config_text(const std::filesystem::path& path) {
  const auto cannot_read = [&](const std::string& reason) {
    return ConfigError(fmt::format("cannot read config file '{}': {}", path.string(), reason));
  };
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) throw cannot_read("is a directory");
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> file(std::fopen(path.c_str(), "rb"),
                                                       &std::fclose);
  if (!file) throw cannot_read(std::generic_category().message(errno));
  std::string text;
  constexpr std::size_t kChunk = 1 << 16;
  std::vector<char> buffer(kChunk);
  std::size_t got = 0;
  while ((got = std::fread(buffer.data(), 1, buffer.size(), file.get())) > 0) {
    text.append(buffer.data(), got);
    // /dev/zero, a FIFO that never ends, a wrong file: not read into memory.
    if (text.size() > kMaxConfigBytes)
      throw cannot_read(fmt::format("larger than {} bytes, not a case file", kMaxConfigBytes));
  }
  if (std::ferror(file.get())) throw cannot_read(std::generic_category().message(errno));
  return text;
}

std::string one_line(std::string_view text) {
  std::string out(text);
  std::replace(out.begin(), out.end(), '\n', ' ');
  std::replace(out.begin(), out.end(), '\r', ' ');
  return out;
}

toml::table parse_config_file(const std::filesystem::path& path) {
  const std::string text = read_config_text(path);
  try {
    return toml::parse(text, std::string_view(path.string()));
  } catch (const toml::parse_error& e) {
    throw ConfigError(fmt::format("{}:{}:{}: {}", path.string(), e.source().begin.line,
                                  e.source().begin.column, one_line(e.description())));
  }
}

/// Puts one `section.name=value` override into the tree.
void apply_override(toml::table& root, const std::string& assignment, std::string_view origin,
                    std::string_view file) {
  const std::size_t eq = assignment.find('=');
  const auto trim = [](std::string_view s) {
    constexpr std::string_view kSpace = " \t";
    const std::size_t b = s.find_first_not_of(kSpace);
    if (b == std::string_view::npos) return std::string();
    return std::string(s.substr(b, s.find_last_not_of(kSpace) - b + 1));
  };
  const std::string key =
      eq == std::string::npos ? std::string() : trim(std::string_view(assignment).substr(0, eq));
  if (key.empty()) {
    throw ConfigError(fmt::format("--set '{}': expected KEY=VALUE, e.g. --set case.M=20",
                                  echo_input(assignment)));
  }
  const std::string value = trim(std::string_view(assignment).substr(eq + 1));

  // The value in TOML syntax; anything that is not a single TOML value is a string.
  std::optional<toml::table> parsed;
  try {
    parsed = toml::parse("v = " + value, origin);
  } catch (const toml::parse_error&) {
    parsed.reset();
  }
  if (parsed && (parsed->size() != 1 || !parsed->contains("v"))) parsed.reset();

  const std::size_t dot = key.find('.');
  toml::table* target = &root;
  std::string name = key;
  if (dot != std::string::npos) {
    const std::string section = key.substr(0, dot);
    name = key.substr(dot + 1);
    toml::node* existing = root.get(section);
    if (!existing) {
      root.insert(section, toml::table{});
      existing = root.get(section);
    }
    target = existing->as_table();
    if (!target) {
      fail_value(section, node_text(*existing),
                 fmt::format("must be a table (section [{}])", section),
                 node_origin(*existing, file));
    }
  }
  if (parsed) {
    parsed->get("v")->visit([&](auto&& node) { target->insert_or_assign(name, std::move(node)); });
  } else {
    target->insert_or_assign(name, value);
  }
}

using GivenMap = Inputs::GivenMap;

/// Checks the structure (sections, keys) first, then every value.
GivenMap collect(const toml::table& root, const ParameterSet& set, std::string_view file) {
  for (auto&& [section_key, section_node] : root) {
    const std::string section(section_key.str());
    const auto* table = section_node.as_table();
    if (!is_known_section(set, section)) {
      if (table && !table->empty()) {
        const auto first = table->cbegin();
        const std::string key = section + "." + std::string(first->first.str());
        throw ConfigError(
            fmt::format("unknown key '{}' (unknown section [{}]; known sections: {}){}",
                        echo_input(key), echo_input(section), section_list(set),
                        origin_suffix(node_origin(first->second, file))),
            key);
      }
      if (table) {
        throw ConfigError(
            fmt::format("unknown section '[{}]' (known sections: {}){}", echo_input(section),
                        section_list(set), origin_suffix(node_origin(section_node, file))),
            section);
      }
      throw ConfigError(
          fmt::format(
              "unknown key '{}' (keys belong to a section: {}; write [section] or section.key){}",
              echo_input(section), section_list(set),
              origin_suffix(node_origin(section_node, file))),
          section);
    }
    if (!table) {
      fail_value(section, node_text(section_node),
                 fmt::format("must be a table (section [{}])", section),
                 node_origin(section_node, file));
    }
    for (auto&& [name, node] : *table) {
      const std::string key = section + "." + std::string(name.str());
      if (!set.find(key)) {
        throw ConfigError(
            fmt::format("unknown key '{}' (known keys in [{}]: {}){}", echo_input(key), section,
                        keys_in_section(set, section), origin_suffix(node_origin(node, file))),
            key);
      }
    }
  }
  GivenMap given;
  for (auto&& [section_key, section_node] : root) {
    for (auto&& [name, node] : *section_node.as_table()) {
      const std::string key = std::string(section_key.str()) + "." + std::string(name.str());
      given.emplace(key, convert(*set.find(key), node, file));
    }
  }
  return given;
}

}  // namespace

bool Inputs::any_in_section(std::string_view section) const {
  return std::any_of(given_.begin(), given_.end(), [&](const auto& entry) {
    return std::string_view(entry.first).substr(0, entry.first.find('.')) == section;
  });
}

const ParameterValue& Inputs::default_of(std::string_view key) const {
  const ParameterSpec* spec = set_->find(key);
  if (!spec || !spec->default_value) {
    throw std::logic_error("parameter registry: no default for '" + std::string(key) + "'");
  }
  return *spec->default_value;
}

double Inputs::required_real(const std::string& key, const std::string& why) const {
  if (const Given* g = given(key)) return std::get<double>(g->value);
  throw ConfigError(fmt::format("{} is required {}", key, why), key);
}

void Inputs::fail(const std::string& key, const std::string& problem) const {
  const Given* g = given(key);
  if (!g) {
    // A default the other inputs rule out: name its value as if given.
    const ParameterSpec* spec = set_->find(key);
    if (!spec || !spec->default_value) throw ConfigError(fmt::format("{}: {}", key, problem), key);
    throw ConfigError(
        fmt::format("{} = {} (the default): {}", key, spec->default_description(), problem), key);
  }
  fail_value(key, g->text, problem, g->origin);
}

Inputs read_inputs(const ParameterSet& set, const std::optional<std::filesystem::path>& file,
                   const std::vector<std::string>& overrides, std::string_view origin) {
  toml::table root = file ? parse_config_file(*file) : toml::table{};
  const std::string file_path = file ? file->string() : std::string();
  for (const auto& assignment : overrides) apply_override(root, assignment, origin, file_path);
  return Inputs(collect(root, set, file_path), set);
}

SolverSettings assemble_solver(const Inputs& in) {
  SolverSettings c;
  c.cycle = in.get<std::string>("solver.cycle") == kCycleW ? CycleType::W : CycleType::V;
  c.tolerance = in.real("solver.tolerance");
  c.max_cycles = in.integer("solver.max_cycles");
  c.pre_sweeps = in.integer("solver.pre_sweeps");
  c.post_sweeps = in.integer("solver.post_sweeps");
  c.coarsest_points = in.integer("solver.coarsest_points");
  c.relaxation.switch_ratio = in.real("solver.switch_ratio");
  c.relaxation.omega_gauss_seidel = in.real("solver.omega_gauss_seidel");
  c.relaxation.omega_flow_dominated = in.real("solver.omega_flow_dominated");
  c.relaxation.omega_jacobi = in.real("solver.omega_jacobi");
  c.relaxation.alternate_directions =
      in.get<std::string>("solver.line_directions") == kLinesAlternating;
  c.relaxation.deformation_each_colour =
      in.get<std::string>("solver.deformation_updates") == kUpdatesPerColour;
  c.face_mean = face_mean_from_text(in.get<std::string>("solver.face_mean"));
  c.deformation = in.get<std::string>("solver.deformation") == kDirect ? DeformationMethod::Direct
                                                                       : DeformationMethod::Fft;
  c.memory_limit_mb = in.optional_real("solver.memory_limit_mb").value_or(0.0);
  c.local_newton_half_width = in.integer("solver.local_newton");
  c.local_newton_windows = in.integer("solver.local_newton_windows");
  const int grid_points = in.integer("grid.points");
  // The default on a grid coarser than it: the grid is its only level.
  if (!in.has("solver.coarsest_points"))
    c.coarsest_points = std::min(c.coarsest_points, grid_points);
  if (c.coarsest_points > grid_points) {
    in.fail("solver.coarsest_points", fmt::format("must be <= grid.points ({})", grid_points));
  }
  if (c.pre_sweeps + c.post_sweeps < 1) {
    const std::string key =
        in.has("solver.post_sweeps") ? "solver.post_sweeps" : "solver.pre_sweeps";
    in.fail(key,
            fmt::format("solver.pre_sweeps + solver.post_sweeps must be >= 1 (they are {} and {})",
                        c.pre_sweeps, c.post_sweeps));
  }
  return c;
}

void add_physical_lubricant_parameters(std::vector<ParameterSpec>& r) {
  r.push_back(real("physical.eta0", kNoDefault, "none", above(0), kUnbounded, "Pa s",
                   "ambient viscosity of the lubricant"));
  r.push_back(real("physical.alpha", kNoDefault, "none", at_least(0), kUnbounded, "1/Pa",
                   "pressure-viscosity coefficient (alpha_bar = alpha times the Hertz pressure)"));
}

void add_body_and_grid_points_parameters(std::vector<ParameterSpec>& r, int default_points) {
  r.push_back(
      boolean("body.elastic", true, "elastic deformation of the surfaces (false: rigid bodies)"));
  r.push_back(integer("grid.points", default_points, at_least(kMinGridPoints),
                      at_most(kMaxGridPoints), true, "points per side of the square grid"));
}

void add_lubricant_parameters(std::vector<ParameterSpec>& r) {
  // [lubricant]
  r.push_back(
      choice("lubricant.viscosity", kBarus, {std::string(kBarus), std::string(kRoelands)},
             "viscosity law: barus exp(alpha_bar P), or roelands (needs eta0, z, ph_star)"));
  r.push_back(choice("lubricant.density", kIncompressible,
                     {std::string(kIncompressible), std::string(kDowsonHigginson)},
                     "density law: incompressible, or dowson-higginson (needs ph_star)"));
  r.push_back(real("lubricant.eta0", kNoDefault, "physical.eta0", above(0), kUnbounded, "Pa s",
                   "roelands: ambient viscosity"));
  r.push_back(real("lubricant.z", kNoDefault, "from lubricant.alpha", at_least(0), kUnbounded, "",
                   "roelands: pressure-viscosity index z (or give lubricant.alpha)"));
  r.push_back(
      real("lubricant.alpha", kNoDefault, "physical.alpha, else alpha_bar / ph_star", at_least(0),
           kUnbounded, "1/Pa",
           "roelands: alpha, converted to z = alpha p0 / (ln(eta0) + 9.67), p0 = 1.96e8 Pa"));
  r.push_back(real("lubricant.ph_star", kNoDefault, "ph* of [physical]", above(0), kUnbounded, "Pa",
                   "reference Hertz pressure, needed by roelands and dowson-higginson"));
}

namespace {

/// The keys of the line relaxation, shared by every mode that solves Reynolds.
void add_relaxation_parameters(std::vector<ParameterSpec>& r,
                               const reynolds::RelaxationSettings& relax) {
  r.push_back(real("solver.switch_ratio", relax.switch_ratio, "", above(0), kUnbounded, "",
                   "a point is relaxed by Gauss-Seidel where its flow coefficients exceed this "
                   "times the elastic coefficient of its transport term, else by distributive "
                   "Jacobi (impact: on each multigrid level of mesh h finer than 3/256, this times "
                   "(3/256) / h)"));
  r.push_back(real("solver.omega_gauss_seidel", relax.omega_gauss_seidel, "", above(0), at_most(1),
                   "", "under-relaxation of the Gauss-Seidel line changes"));
  r.push_back(real("solver.omega_flow_dominated", relax.omega_flow_dominated, "", above(0),
                   at_most(1), "",
                   fmt::format("under-relaxation of the Gauss-Seidel line changes at points "
                               "whose flow coefficients exceed {:g} times the switch's bound, or "
                               "that have no elastic term (cavitated, rigid bodies)",
                               reynolds::kFlowDominatedFactor)));
  r.push_back(real("solver.omega_jacobi", relax.omega_jacobi, "", above(0), at_most(1), "",
                   "under-relaxation of the distributive Jacobi line changes"));
  r.push_back(choice("solver.line_directions",
                     relax.alternate_directions ? kLinesAlternating : kLinesX,
                     {std::string(kLinesAlternating), std::string(kLinesX)},
                     "relaxation lines: along X and Y in turn (alternating), or along X only"));
  r.push_back(choice("solver.deformation_updates",
                     relax.deformation_each_colour ? kUpdatesPerColour : kUpdatesPerSweep,
                     {std::string(kUpdatesPerSweep), std::string(kUpdatesPerColour)},
                     "the relaxation recomputes the elastic deformation once per sweep (and "
                     "for its second colour where elastically coupled Gauss-Seidel points "
                     "outnumber distributive ones), or before each of its two colours"));
}

}  // namespace

void add_solver_parameters(std::vector<ParameterSpec>& r, const SolverSettings& defaults,
                           const std::string& max_cycles_doc) {
  r.push_back(choice("solver.cycle", cycle_type_text(defaults.cycle),
                     {std::string(kCycleV), std::string(kCycleW)}, "multigrid cycle type"));
  r.push_back(real("solver.tolerance", defaults.tolerance, "", above(0), at_most(kMaxTolerance), "",
                   "converged when the scaled finest-grid residual is below this"));
  r.push_back(integer("solver.max_cycles", defaults.max_cycles, at_least(1), kUnbounded, false,
                      max_cycles_doc));
  r.push_back(integer("solver.pre_sweeps", defaults.pre_sweeps, at_least(0), at_most(kMaxSweeps),
                      false, "relaxation sweeps before the coarse-grid correction"));
  r.push_back(integer("solver.post_sweeps", defaults.post_sweeps, at_least(0), at_most(kMaxSweeps),
                      false, "relaxation sweeps after it (pre_sweeps + post_sweeps >= 1)"));
  r.push_back(
      integer("solver.coarsest_points", defaults.coarsest_points, at_least(kMinCoarsestPoints),
              at_most(kMaxGridPoints), true,
              "points per side of the coarsest multigrid level (<= grid.points; the default is "
              "grid.points on a grid with fewer points)"));
  r.push_back(choice("solver.deformation", deformation_method_text(defaults.deformation),
                     {std::string(kFft), std::string(kDirect)},
                     "deformation integrals: fft (zero-padded FFT convolution) or direct"));
  add_relaxation_parameters(r, defaults.relaxation);
  r.push_back(choice("solver.face_mean", face_mean_text(defaults.face_mean),
                     {std::string(kArithmetic), std::string(kHarmonic), std::string(kLogarithmic)},
                     "flow coefficient on a cell face: arithmetic (Venner & Lubrecht), harmonic, "
                     "or logarithmic mean of the two points (exact flux for Barus at constant H)"));
  r.push_back(real("solver.memory_limit_mb", kNoDefault,
                   "the available memory (MemAvailable of /proc/meminfo)", above(0), kUnbounded,
                   "MB",
                   "refuse a run whose memory estimate (run.json: invocation.memory) exceeds "
                   "this, before it starts"));
  r.push_back(integer("solver.local_newton", defaults.local_newton_half_width, at_least(0),
                      at_most(kMaxLocalNewtonHalfWidth), false,
                      "after each cycle that leaves the finest grid above the tolerance, one "
                      "Newton step on the points within this many meshes of the largest "
                      "residuals (0: none)"));
  r.push_back(integer("solver.local_newton_windows", defaults.local_newton_windows, at_least(0),
                      at_most(kMaxLocalNewtonWindows), false,
                      "the most windows of each local Newton step, centred on the largest "
                      "residuals, no two overlapping (0: one per 32 points of the side of the "
                      "grid solved on: 16 on the quadrant of 1025^2)"));
}

/// The Roelands law's own inputs would be ignored by Barus's: most likely the
/// law was meant to be Roelands.
void refuse_roelands_inputs(const Inputs& in) {
  for (const char* key : {"lubricant.z", "lubricant.alpha", "lubricant.eta0"}) {
    if (in.has(key))
      in.fail(key, "is used only by lubricant.viscosity = \"roelands\" (the law is \"barus\")");
  }
}

/// The Roelands index z of `lub` (whose eta0 and ph* are set): lubricant.z,
/// or from the pressure-viscosity coefficient alpha.
double roelands_z(const Inputs& in, const Lubricant& lub, double alpha_bar,
                  const std::optional<PhysicalLubricant>& physical, const std::string& user) {
  if (!(lub.eta0_Pa_s > 0.0)) {
    throw ConfigError(fmt::format("lubricant.eta0 is required by {} (ambient viscosity [Pa s]; or "
                                  "give a [physical] section)",
                                  user),
                      "lubricant.eta0");
  }
  if (!(std::log(lub.eta0_Pa_s) + kRoelandsLnEtaInf > 0.0)) {
    const std::string key = physical ? "physical.eta0" : "lubricant.eta0";
    in.fail(key, fmt::format("must be > {:g} Pa s for the Roelands law (ln(eta0) + {} > 0)",
                             std::exp(-kRoelandsLnEtaInf), kRoelandsLnEtaInf));
  }
  if (in.has("lubricant.z") && in.has("lubricant.alpha")) {
    in.fail("lubricant.alpha", "give either lubricant.z or lubricant.alpha, not both");
  }
  if (const auto z = in.optional_real("lubricant.z")) return *z;
  // Default alpha: the one of [physical], else the one L implies (alpha_bar / ph*).
  const double alpha =
      physical ? physical->alpha_per_Pa
               : in.optional_real("lubricant.alpha").value_or(alpha_bar / lub.ph_star_Pa);
  return Lubricant::roelands_z_from_alpha(alpha, lub.eta0_Pa_s);
}

Lubricant assemble_lubricant(const Inputs& in, double alpha_bar,
                             const std::optional<PhysicalLubricant>& physical) {
  Lubricant lub;
  lub.alpha_bar = alpha_bar;
  lub.viscosity = in.get<std::string>("lubricant.viscosity") == kRoelands ? ViscosityModel::Roelands
                                                                          : ViscosityModel::Barus;
  lub.density = in.get<std::string>("lubricant.density") == kDowsonHigginson
                    ? DensityModel::DowsonHigginson
                    : DensityModel::Incompressible;
  const bool roelands = lub.viscosity == ViscosityModel::Roelands;
  const bool dowson_higginson = lub.density == DensityModel::DowsonHigginson;
  const std::string user =
      roelands ? "lubricant.viscosity = \"roelands\"" : "lubricant.density = \"dowson-higginson\"";

  // Inputs the [physical] section already fixes.
  if (physical) {
    for (const char* key : {"lubricant.ph_star", "lubricant.eta0", "lubricant.alpha"}) {
      if (in.has(key)) in.fail(key, "is given by the [physical] section; remove one of them");
    }
  }
  lub.ph_star_Pa =
      physical ? physical->ph_star_Pa : in.optional_real("lubricant.ph_star").value_or(0.0);
  lub.eta0_Pa_s = physical ? physical->eta0_Pa_s : in.optional_real("lubricant.eta0").value_or(0.0);
  lub.roelands_z = 0.0;
  if ((roelands || dowson_higginson) && !(lub.ph_star_Pa > 0.0)) {
    throw ConfigError(fmt::format("lubricant.ph_star is required by {} (reference Hertz pressure "
                                  "[Pa]; or give a [physical] section)",
                                  user),
                      "lubricant.ph_star");
  }
  if (!roelands) {
    refuse_roelands_inputs(in);
    return lub;
  }
  lub.roelands_z = roelands_z(in, lub, alpha_bar, physical, user);
  return lub;
}

// A radius of 1e300 m in a [physical] section gave W = 0 and M = 0 x inf =
// NaN, and case.M = 1e300 gave lambda_bar = 0: runs that failed at their
// first step with "residual not finite".
void check_moes_groups(const Inputs& in, const MoesGroups& g, const std::string& load_key,
                       const std::string& lubricant_key) {
  const auto positive = [](double v) { return std::isfinite(v) && v > 0.0; };
  const auto non_negative = [](double v) { return std::isfinite(v) && v >= 0.0; };
  const bool load_ok = positive(g.M) && positive(g.lambda_bar);
  if (load_ok && non_negative(g.L) && non_negative(g.alpha_bar)) return;
  const bool physical = in.any_in_section("physical");
  const std::string key = physical ? "physical" : load_ok ? lubricant_key : load_key;
  in.fail(key,
          fmt::format("{} M = {}, L = {}, lambda_bar = {} and alpha_bar = {}, which must "
                      "be finite numbers (M and lambda_bar > 0, L and alpha_bar >= 0)",
                      physical ? "the section's values give" : "gives", finite_or_text(g.M, "{:g}"),
                      finite_or_text(g.L, "{:g}"), finite_or_text(g.lambda_bar, "{:g}"),
                      finite_or_text(g.alpha_bar, "{:g}")));
}

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
  const Lubricant lub = assemble_lubricant(in, c.alpha_bar, physical);
  c.viscosity = lub.viscosity;
  c.density = lub.density;
  c.ph_star_Pa = lub.ph_star_Pa;
  c.eta0_Pa_s = lub.eta0_Pa_s;
  c.roelands_z = lub.roelands_z;
}

/// The undeformed gap at T = 0, Delta0 + (X^2 + Y^2) / 2 + waviness, must be
/// positive at every grid point: a start with the surfaces already through
/// each other is no impact (model.md).  Only the waviness can make it negative.
void check_undeformed_gap(const Inputs& in, const ImpactConfig& c) {
  if (!(c.waviness_amplitude > 0.0)) return;
  const Grid2D grid(c.grid_points, c.half_width);
  double largest = std::numeric_limits<double>::infinity();  // amplitude that keeps the gap > 0
  for (int j = 0; j < grid.n; ++j) {
    for (int i = 0; i < grid.n; ++i) {
      const double x = grid.x(i), y = grid.y(j);
      const double wave = waviness_height(c, x, y) / c.waviness_amplitude;  // cos(...)
      if (wave < 0.0) largest = std::min(largest, (c.Delta0 + 0.5 * (x * x + y * y)) / -wave);
    }
  }
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

/// An elastic ball's dry contact must fit into the domain, and its duration
/// must span kMinStepsPerDryContact time steps: else the run can only fail or
/// give a result of the discretisation (model.md, "Reference values").  A
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
  in.fail(in.has("grid.half_width") ? "grid.half_width" : "grid.points",
          fmt::format("gives a mesh, and so a default time.dT, of {:.4g}; it must be <= {:.4g} "
                      "({}): set time.dT or use a finer mesh",
                      dT, largest_dT, why));
}

/// A run of more than kMaxTimeSteps steps is refused before it starts: a
/// start far away or slow needs billions of steps (and an int overflows).
void check_step_count(const Inputs& in, const ImpactConfig& c) {
  const double dT = effective_time_step(c);
  const double limit = kMaxTimeSteps;
  if (std::isfinite(c.T_end)) {
    const double steps = std::ceil(c.T_end / dT);
    if (steps <= limit) return;
    in.fail("time.T_end",
            fmt::format("needs {:.3g} time steps of time.dT = {:.4g}; at most {} are allowed",
                        steps, dT, kMaxTimeSteps));
  }
  if (in.has("time.max_steps")) return;  // within the registry's range
  const double steps = default_max_steps_exact(c.Delta0, c.V0, dT);
  if (steps <= limit) return;
  const bool slow = in.has("time.V0") || !in.has("time.Delta0");
  const std::string start = slow ? fmt::format("from time.Delta0 = {:g}", c.Delta0)
                                 : fmt::format("at time.V0 = {:g}", c.V0);
  in.fail(slow ? "time.V0" : "time.Delta0",
          fmt::format("a run until lift-off {} may need {:.3g} time steps of dT = {:.4g} (the "
                      "default time.max_steps, 4 (Delta0 / V0 + 3.2181 V0^-0.2) / dT); at most {} "
                      "are allowed: start closer or faster, or set time.T_end or time.max_steps",
                      start, steps, dT, kMaxTimeSteps));
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
  static_cast<SolverSettings&>(c) = assemble_solver(in);
  c.correction_safeguard = in.real("solver.correction_safeguard");
  c.retry_damping = in.real("solver.retry_damping");
  c.force_tolerance = in.real("solver.force_tolerance");
  c.contracting_start = in.get<bool>("solver.contracting_start");
  c.use_symmetry = in.get<std::string>("solver.symmetry") == kSymmetryAuto;
  check_waviness_resolved(in, c);
  check_undeformed_gap(in, c);
  check_dry_contact_resolved(in, c);
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

std::string describe_parameters(const ParameterSet& set) {
  std::string out = set.intro;
  const auto type_name = [](const ParameterSpec& s) -> std::string {
    switch (s.type) {
      case ParameterType::Float:
        return "float";
      case ParameterType::Int:
        return "integer";
      case ParameterType::Bool:
        return "bool";
      case ParameterType::Enum:
        return "string";
      case ParameterType::FloatArray:
        return "float array";
    }
    return {};
  };
  for (const auto& section : set.sections) {
    out += fmt::format("\n[{}]  {}\n", section.name, section.doc);
    for (const auto& s : set.specs) {
      if (s.section() != section.name) continue;
      std::string type = type_name(s);
      if (!s.units.empty()) type += " [" + s.units + "]";
      std::string allowed = s.allowed();
      if (s.type == ParameterType::Float && s.allow_infinite) allowed += " or inf";
      out += fmt::format("  {} = {}  ({}, {})\n      {}\n", s.key, s.default_description(), type,
                         allowed, s.doc);
    }
  }
  return out;
}

double effective_time_step(const ImpactConfig& config) {
  if (config.dT > 0.0) return config.dT;
  return Grid2D(config.grid_points, config.half_width).h();
}

std::string_view spike_filter_text(SpikeFilter filter) {
  for (const auto& [value, name] : kSpikeFilterNames) {
    if (value == filter) return name;
  }
  throw std::logic_error("spike_filter_text: unknown filter");
}

nlohmann::json solver_settings_json(const SolverSettings& c) {
  return {{"cycle", cycle_type_text(c.cycle)},
          {"tolerance", c.tolerance},
          {"max_cycles", c.max_cycles},
          {"pre_sweeps", c.pre_sweeps},
          {"post_sweeps", c.post_sweeps},
          {"coarsest_points", c.coarsest_points},
          {"deformation", deformation_method_text(c.deformation)},
          {"switch_ratio", c.relaxation.switch_ratio},
          {"omega_gauss_seidel", c.relaxation.omega_gauss_seidel},
          {"omega_flow_dominated", c.relaxation.omega_flow_dominated},
          {"omega_jacobi", c.relaxation.omega_jacobi},
          {"line_directions", c.relaxation.alternate_directions ? kLinesAlternating : kLinesX},
          {"deformation_updates",
           c.relaxation.deformation_each_colour ? kUpdatesPerColour : kUpdatesPerSweep},
          {"face_mean", face_mean_text(c.face_mean)},
          {"memory_limit_mb",
           c.memory_limit_mb > 0.0 ? nlohmann::json(c.memory_limit_mb) : nlohmann::json(nullptr)},
          {"local_newton", c.local_newton_half_width},
          {"local_newton_windows", c.local_newton_windows}};
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
  j["lubricant"] = {{"viscosity", viscosity_model_text(c.viscosity)},
                    {"density", density_model_text(c.density)}};
  if (c.viscosity == ViscosityModel::Roelands) {
    j["lubricant"]["eta0"] = c.eta0_Pa_s;
    j["lubricant"]["z"] = c.roelands_z;
  }
  if (c.ph_star_Pa > 0.0) j["lubricant"]["ph_star"] = c.ph_star_Pa;
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
