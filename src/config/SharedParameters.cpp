// The declarations both modes share (the lubricant, the solids, the
// multigrid settings), their assembly from validated inputs and their echo,
// and the TOML strings of the enumerations.
#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "config/ParameterSet.hpp"
#include "grid/NumberText.hpp"
#include "reynolds/LineRelaxation.hpp"

namespace ehlsim {

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
constexpr std::string_view kArithmetic = "arithmetic";
constexpr std::string_view kHarmonic = "harmonic";
constexpr std::string_view kLogarithmic = "logarithmic";
/// solver.coarse_face_mean: the coarse levels take solver.face_mean ...
constexpr std::string_view kSameFaceMean = "same";
/// ... or what the mode chooses for the case (assemble_solver).
constexpr std::string_view kAutoFaceMean = "auto";
constexpr std::string_view kLinesAlternating = "alternating";
constexpr std::string_view kLinesX = "x";
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

namespace {
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
}  // namespace

SolverSettings assemble_solver(const Inputs& in, std::optional<FaceMean> auto_coarse_face_mean) {
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
      in.get<std::string>("solver.deformation_updates") == reynolds::kUpdatesPerColour;
  c.face_mean = face_mean_from_text(in.get<std::string>("solver.face_mean"));
  if (const std::string coarse = in.get<std::string>("solver.coarse_face_mean");
      coarse == kAutoFaceMean)
    c.coarse_face_mean = auto_coarse_face_mean;
  else if (coarse != kSameFaceMean)
    c.coarse_face_mean = face_mean_from_text(coarse);
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
  r.push_back(
      choice("solver.deformation_updates",
             reynolds::deformation_updates_text(relax.deformation_each_colour),
             {std::string(reynolds::kUpdatesPerSweep), std::string(reynolds::kUpdatesPerColour)},
             "the relaxation recomputes the elastic deformation once per sweep (and "
             "for its second colour where elastically coupled Gauss-Seidel points "
             "outnumber distributive ones), or before each of its two colours"));
}

}  // namespace

void add_solver_parameters(std::vector<ParameterSpec>& r, const SolverSettings& defaults,
                           const std::string& tolerance_doc, const std::string& max_cycles_doc) {
  r.push_back(choice("solver.cycle", cycle_type_text(defaults.cycle),
                     {std::string(kCycleV), std::string(kCycleW)}, "multigrid cycle type"));
  r.push_back(real("solver.tolerance", defaults.tolerance, "", above(0), at_most(kMaxTolerance), "",
                   tolerance_doc));
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
  r.push_back(choice("solver.coarse_face_mean", kAutoFaceMean,
                     {std::string(kAutoFaceMean), std::string(kSameFaceMean),
                      std::string(kArithmetic), std::string(kHarmonic), std::string(kLogarithmic)},
                     "face mean of the coarse multigrid levels: same (solver.face_mean), one of "
                     "its means, or auto (logarithmic for an impact at L >= 20, where it saves "
                     "7-27 % of the work and much more on 1025^2; else same: it is harmful in "
                     "the rolling contact); changes the iteration, not its solution "
                     "(docs/performance.md)"));
  r.push_back(real("solver.memory_limit_mb", kNoDefault,
                   "the available memory (MemAvailable of /proc/meminfo)", above(0), kUnbounded,
                   "MB",
                   "refuse a run whose memory estimate (run.json: invocation.memory) exceeds "
                   "this, before it starts"));
  r.push_back(integer("solver.local_newton", defaults.local_newton_half_width, at_least(0),
                      at_most(kMaxLocalNewtonHalfWidth), false,
                      "after each cycle that leaves the finest grid above the tolerance, one "
                      "Newton step on the points within this many meshes of the largest "
                      "residuals (0: none; each window is a dense solve of (2n+1)^2 unknowns: "
                      "20 costs about 0.4 s per cycle on 65^2, 6 about 0.005 s)"));
  r.push_back(integer("solver.local_newton_windows", defaults.local_newton_windows, at_least(0),
                      at_most(kMaxLocalNewtonWindows), false,
                      "the most windows of each local Newton step, centred on the largest "
                      "residuals, no two overlapping (0: one per 32 points of the side of the "
                      "grid solved on, e.g. 16 on the impact's quadrant of 1025^2)"));
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
  const double z = Lubricant::roelands_z_from_alpha(alpha, lub.eta0_Pa_s);
  // ph* = 1e-300 Pa made z infinite, and the first cycles diverged.
  if (!std::isfinite(z)) {
    const std::string key = physical                    ? "physical.alpha"
                            : in.has("lubricant.alpha") ? "lubricant.alpha"
                                                        : "lubricant.ph_star";
    in.fail(key, fmt::format("gives a Roelands index z = alpha p0 / (ln(eta0) + {}) that is "
                             "not finite (alpha = {:g} 1/Pa)",
                             kRoelandsLnEtaInf, alpha));
  }
  return z;
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
    // z beside physical.alpha gave a viscosity other than the recorded L's.
    if (in.has("lubricant.z"))
      in.fail("lubricant.z", "is set by physical.alpha of the [physical] section; remove one");
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
  if (!roelands && !dowson_higginson && in.has("lubricant.ph_star")) {
    in.fail("lubricant.ph_star",
            "is used only by lubricant.viscosity = \"roelands\" and lubricant.density = "
            "\"dowson-higginson\" (the laws are \"barus\" and \"incompressible\")");
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

// A Roelands law given its own alpha kept the L of [case], which contradicted
// it: case.L = 0 with lubricant.alpha = 2e-8 compared the rolling film with
// the formula of L = 0 (243 % above it), and the impact recorded an alpha_bar
// its viscosity did not have.
MoesGroups with_lubricant_L(const Inputs& in, const Lubricant& lub, MoesGroups g,
                            std::initializer_list<const char*> L_keys,
                            const std::string& load_key) {
  const bool own = in.has("lubricant.z") || in.has("lubricant.alpha");
  // (Beside a [physical] section assemble_lubricant refused both keys.)
  if (lub.viscosity != ViscosityModel::Roelands || !own) return g;
  const std::string key = in.has("lubricant.z") ? "lubricant.z" : "lubricant.alpha";
  for (const char* L_key : L_keys) {
    if (in.has(L_key))
      in.fail(L_key,
              fmt::format("cannot be given together with {}: the Roelands law's "
                          "pressure-viscosity coefficient sets L and alpha_bar (give one of them)",
                          key));
  }
  g.alpha_bar = lub.roelands_alpha() * lub.ph_star_Pa;
  g.L = moes_L(g.lambda_bar, g.alpha_bar);
  check_moes_groups(in, g, load_key, key);
  return g;
}

nlohmann::json lubricant_json(const Lubricant& lub) {
  nlohmann::json j = {{"viscosity", viscosity_model_text(lub.viscosity)},
                      {"density", density_model_text(lub.density)}};
  if (lub.viscosity == ViscosityModel::Roelands) {
    j["eta0"] = lub.eta0_Pa_s;
    j["z"] = lub.roelands_z;
  }
  if (lub.ph_star_Pa > 0.0) j["ph_star"] = lub.ph_star_Pa;
  return j;
}

std::string lubricant_text(const Lubricant& lub) {
  std::string text =
      fmt::format("{}, {}", viscosity_model_text(lub.viscosity), density_model_text(lub.density));
  if (lub.viscosity == ViscosityModel::Roelands)
    text += fmt::format(" (eta0 = {:.4g} Pa s, z = {:.4g})", lub.eta0_Pa_s, lub.roelands_z);
  if (lub.ph_star_Pa > 0.0) text += fmt::format(", ph* = {:.4g} Pa", lub.ph_star_Pa);
  return text;
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
           reynolds::deformation_updates_text(c.relaxation.deformation_each_colour)},
          {"face_mean", face_mean_text(c.face_mean)},
          {"coarse_face_mean",
           c.coarse_face_mean ? face_mean_text(*c.coarse_face_mean) : kSameFaceMean},
          {"memory_limit_mb",
           c.memory_limit_mb > 0.0 ? nlohmann::json(c.memory_limit_mb) : nlohmann::json(nullptr)},
          {"local_newton", c.local_newton_half_width},
          {"local_newton_windows", c.local_newton_windows}};
}

}  // namespace ehlsim
