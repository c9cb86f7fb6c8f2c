#include "config/RollingParameters.hpp"

#include <fmt/format.h>

#include <cmath>
#include <numbers>

#include "config/Parameters.hpp"
#include "impact/Scaling.hpp"
#include "rolling/DryEllipticHertz.hpp"
#include "rolling/RollingProblem.hpp"

namespace ehlsim {

namespace {
/// Most cycles per coarse grid of the full multigrid start.  A coarse stage
/// runs all of them (only the finest grid stops at the tolerance), so 1e9
/// would run for days; 200 is the most tried (docs/validation.md, "M = 10,
/// L = 20": it did not help).
constexpr int kMaxFmgCycles = 200;
/// The smallest case.D (and the inverse of the largest): the dry Hertz
/// ellipse that sizes the start and the domain check is finite from 1e-295
/// to 1e295 (Rolling.EllipticHertzStaysFiniteAndMonotonicOverEveryD); at D =
/// 5e-324 it reached infinity and the domain check said "must be < -inf".
constexpr double kMinEllipticity = 1e-295;

const RollingConfig kDefaults{};

std::vector<ParameterSpec> build_rolling_registry() {
  std::vector<ParameterSpec> r;
  // [case]
  r.push_back(real("case.M", kDefaults.M, "", above(0), kUnbounded, "",
                   "Moes load parameter W U^(-3/4); sets lambda_bar = (128 pi^3 / (3 M^4))^(1/3)"));
  r.push_back(
      real("case.L", kDefaults.L, "", at_least(0), kUnbounded, "",
           "Moes lubricant parameter alpha E' U^(1/4); alpha_bar = (L / pi) (3 M / 2)^(1/3)"));
  r.push_back(real("case.D", kDefaults.D, "", at_least(kMinEllipticity),
                   at_most(1.0 / kMinEllipticity), "",
                   "ellipticity of the gap Rx / Ry (1: a ball; Rx along the rolling)"));
  // [physical]
  r.push_back(real("physical.Rx", kNoDefault, "none", above(0), kUnbounded, "m",
                   "reduced radius of curvature along the rolling direction"));
  r.push_back(real("physical.Ry", kNoDefault, "physical.Rx", above(0), kUnbounded, "m",
                   "reduced radius of curvature across it"));
  r.push_back(
      real("physical.load", kNoDefault, "none", above(0), kUnbounded, "N", "normal load w"));
  r.push_back(real("physical.u1", kNoDefault, "none", at_least(0), kUnbounded, "m/s",
                   "surface speed of body 1"));
  r.push_back(real("physical.u2", kNoDefault, "none", at_least(0), kUnbounded, "m/s",
                   "surface speed of body 2 (u1 + u2 > 0; sliding does not change the "
                   "isothermal Newtonian film)"));
  r.push_back(real("physical.reduced_modulus", kNoDefault, "none", above(0), kUnbounded, "Pa",
                   "reduced modulus E'"));
  add_physical_lubricant_parameters(r);
  add_lubricant_parameters(r);
  add_body_and_grid_points_parameters(r, kDefaults.grid_points);
  r.push_back(
      real("grid.x_min", kDefaults.x_min, "", kUnbounded, below(0), "", "inlet edge (unit: a)"));
  r.push_back(real("grid.x_max", kDefaults.x_max, "", above(0), kUnbounded, "", "outlet edge"));
  r.push_back(real("grid.y_min", kDefaults.y_min, "", kUnbounded, below(0), "",
                   "side edge; y_max - y_min = x_max - x_min (square cells on a square grid)"));
  r.push_back(real("grid.y_max", kDefaults.y_max, "", above(0), kUnbounded, "", "other side edge"));
  // [solver]
  add_solver_parameters(r, kDefaults,
                        "converged when the scaled finest-grid residual and the relative force "
                        "error are both below this",
                        "cycles on the finest grid, of all its attempts, before the run is solved "
                        "again with the other deformation update (solver.fallback_update) or "
                        "fails (exit 1)");
  r.push_back(real("solver.h0_relaxation", kDefaults.h0_relaxation, "", above(0), at_most(1), "",
                   "fraction of the Newton change of H0 (force balance) applied after a cycle"));
  r.push_back(integer("solver.fmg_cycles", kDefaults.fmg_cycles, at_least(1),
                      at_most(kMaxFmgCycles), false,
                      "cycles on each coarser grid of the full multigrid start"));
  r.push_back(boolean("solver.fallback_update", kDefaults.fallback_update,
                      "an elastic contact that runs out of cycles solves again from its start "
                      "with the other deformation update (solver.deformation_updates)"));
  return r;
}

/// Fails unless D = Rx / Ry of the radii `p` lies in case.D's range, naming
/// both radii and blaming the one that drives it out (a large Rx or a small
/// Ry above, the reverse below): the further from 1 m on that side.
/// physical.Rx = 1e308 was told as the file's physical.Ry = 0.0127, and a D
/// of 1e-308, finite, passed on to "grid.x_min ...: must be < -inf".  Ry is
/// given whenever D fails (its default, Rx, gives D = 1).
void check_radii_ratio(const Inputs& in, const RollingPhysical& p, double D) {
  if (D >= kMinEllipticity && D <= 1.0 / kMinEllipticity) return;
  const double log_product = std::log(p.Rx_m) + std::log(p.Ry_m);
  const bool rx = D > 1.0 ? log_product > 0.0 : log_product < 0.0;
  const char* other_key = rx ? "physical.Ry" : "physical.Rx";
  const Given* other = in.given(other_key);
  const std::string with =
      other ? fmt::format("with {} = {} ({}) ", other_key, other->text, other->origin) : "";
  in.fail(rx ? "physical.Rx" : "physical.Ry",
          fmt::format("{}gives D = Rx / Ry = {:g}, which must be in [{:g}, {:g}] (case.D's range)",
                      with, D, kMinEllipticity, 1.0 / kMinEllipticity));
}

/// M, L, D and the Hertz scales of a case given in SI units (model.md).
void assemble_physical(const Inputs& in, RollingConfig& c) {
  const std::string why = "with a [physical] section";
  RollingPhysical p;
  p.Rx_m = in.required_real("physical.Rx", why);
  p.Ry_m = in.optional_real("physical.Ry").value_or(p.Rx_m);
  p.load_N = in.required_real("physical.load", why);
  p.u1_m_s = in.required_real("physical.u1", why);
  p.u2_m_s = in.required_real("physical.u2", why);
  if (!(p.u1_m_s + p.u2_m_s > 0.0)) in.fail("physical.u2", "u1 + u2 must be > 0 (no entrainment)");
  p.reduced_modulus_Pa = in.required_real("physical.reduced_modulus", why);
  p.eta0_Pa_s = in.required_real("physical.eta0", why);
  p.alpha_per_Pa = in.required_real("physical.alpha", why);
  const double E = p.reduced_modulus_Pa;
  p.a_m = std::cbrt(1.5 * p.load_N * p.Rx_m / E);
  p.ph_Pa = 1.5 * p.load_N / (std::numbers::pi * p.a_m * p.a_m);
  p.U = p.eta0_Pa_s * (p.u1_m_s + p.u2_m_s) / (E * p.Rx_m);
  p.W = p.load_N / (E * p.Rx_m * p.Rx_m);
  c.M = p.W * std::pow(p.U, -0.75);
  c.L = p.alpha_per_Pa * E * std::pow(p.U, 0.25);
  c.D = p.Rx_m / p.Ry_m;
  check_radii_ratio(in, p, c.D);
  c.physical = p;
}

void assemble_rolling_case(const Inputs& in, RollingConfig& c) {
  if (in.any_in_section("physical")) {
    for (const char* key : {"case.M", "case.L", "case.D"})
      if (in.has(key)) in.fail(key, "cannot be combined with a [physical] section");
    assemble_physical(in, c);
  } else {
    c.M = in.real("case.M");
    c.L = in.real("case.L");
    c.D = in.real("case.D");
  }
  c.lambda_bar = moes_lambda_bar(c.M);
  c.alpha_bar = moes_alpha_bar(c.M, c.L);
  check_moes_groups(in, {c.M, c.L, c.lambda_bar, c.alpha_bar}, "case.M", "case.L");
  std::optional<PhysicalLubricant> physical;
  if (c.physical) physical = {c.physical->ph_Pa, c.physical->eta0_Pa_s, c.physical->alpha_per_Pa};
  c.lubricant = assemble_lubricant(in, c.alpha_bar, physical);
  const MoesGroups g = with_lubricant_L(in, c.lubricant, {c.M, c.L, c.lambda_bar, c.alpha_bar},
                                        {"case.L"}, "case.M");
  c.L = g.L;
  c.alpha_bar = g.alpha_bar;
  c.lubricant.alpha_bar = g.alpha_bar;
}

/// The relative difference of the domain's sides that counts as square.
constexpr double kSquareTolerance = 1e-12;

void assemble_rolling_grid(const Inputs& in, RollingConfig& c) {
  c.elastic = in.get<bool>("body.elastic");
  c.grid_points = in.integer("grid.points");
  c.x_min = in.real("grid.x_min");
  c.x_max = in.real("grid.x_max");
  c.y_min = in.real("grid.y_min");
  c.y_max = in.real("grid.y_max");
  const double width = c.x_max - c.x_min, height = c.y_max - c.y_min;
  if (std::abs(width - height) > kSquareTolerance * width) {
    // The key the user gave (x_min = -0.01 alone blamed the default y_min).
    std::string key = "grid.y_min";
    for (const char* given : {"grid.y_max", "grid.y_min", "grid.x_max", "grid.x_min"}) {
      if (in.has(given)) {
        key = given;
        break;
      }
    }
    // 15 digits show a difference of kSquareTolerance ("6 must equal 6" at 10).
    in.fail(key, fmt::format("y_max - y_min = {:.15g} must equal x_max - x_min = {:.15g} (the grid "
                             "is square with square cells)",
                             height, width));
  }
}

/// An elastic contact's dry Hertz ellipse must fit into the domain, as the
/// impact's dry contact must (config/Parameters.cpp): a contact cut by the edges,
/// where P = 0, leaves the force balance nothing but a film of the domain
/// (a ball in [-0.8, 0.8]^2 ran out of cycles with 35 % of the load at the
/// edges).  A rigid body has no dry contact.
void check_dry_contact_resolved(const Inputs& in, const RollingConfig& c) {
  if (!c.elastic) return;
  const EllipticHertzContact hz = dry_elliptic_hertz(c.D);
  const std::string of_case =
      c.physical ? fmt::format("Rx / Ry = {:g}", c.D) : fmt::format("case.D = {:g}", c.D);
  const auto require = [&](const char* key, double edge, double semi_axis, const char* along) {
    if (std::abs(edge) > semi_axis) return;
    in.fail(key, fmt::format("must be {} {:.4g}: the dry Hertz contact at {} reaches {:.4g} {}, "
                             "and the domain must hold it",
                             edge < 0.0 ? "<" : ">", std::copysign(semi_axis, edge), of_case,
                             semi_axis, along));
  };
  require("grid.x_min", c.x_min, hz.ax, "along the rolling (X)");
  require("grid.x_max", c.x_max, hz.ax, "along the rolling (X)");
  require("grid.y_min", c.y_min, hz.ay, "across it (Y)");
  require("grid.y_max", c.y_max, hz.ay, "across it (Y)");
  // ... and the finest grid must resolve it: on a domain 2000 wide, 65^2
  // (mesh 31) ran its 200 cycles to a force error of -1, all pressure gone.
  const double width = c.x_max - c.x_min, mesh = width / (c.grid_points - 1);
  const double widest = widest_resolving_mesh(c);
  if (mesh > widest) {
    int points = c.grid_points;
    while (points < kMaxGridPoints && width / (points - 1) > widest) points = 2 * points - 1;
    // The smallest domain that holds the contact spans both semi-axes' diameters.
    const double least_width = 2.0 * std::max(hz.ax, hz.ay);
    const double least_points = least_width / widest + 1.0;
    std::string remedy = fmt::format("use at least {} points or a smaller domain", points);
    if (least_points > kMaxGridPoints)
      remedy = fmt::format(
          "even the smallest domain that holds the contact ({:.4g} wide) needs about {:.3g} "
          "points per side, more than the {} allowed: this ellipticity is beyond what the grid "
          "can resolve",
          least_width, least_points, kMaxGridPoints);
    else if (width / (points - 1) > widest)
      remedy = "use a smaller domain";
    in.fail("grid.points",
            fmt::format("the mesh, {:.4g}, is wider than the dry Hertz contact's smaller "
                        "semi-axis, {:.4g}, at {}: {}",
                        mesh, widest, of_case, remedy));
  }
}

}  // namespace

const ParameterSet& rolling_parameters() {
  static const ParameterSet set{
      {{"case", "Moes parameters of the rolling contact (dimensionless case)"},
       {"physical", "the case in SI units, instead of [case]: M, L and D follow from it"},
       {"lubricant", "viscosity and density laws"},
       {"body", "the solids"},
       {"grid", "the square computational domain (unit: a, the Hertz radius along X)"},
       {"solver", "multigrid settings"}},
      build_rolling_registry(),
      "Parameters: in CONFIG.toml write [section] then name = value; on the command line\n"
      "--set section.name=VALUE (VALUE in TOML syntax, a bare word is a string; applied after\n"
      "the file, in order). Defaults: a ball, M = 100, L = 10, on 257^2 points.\n"};
  return set;
}

RollingConfig load_rolling_config(const std::optional<std::filesystem::path>& file,
                                  const std::vector<std::string>& overrides) {
  const Inputs in = read_inputs(rolling_parameters(), file, overrides);
  RollingConfig c;
  assemble_rolling_case(in, c);
  assemble_rolling_grid(in, c);
  check_dry_contact_resolved(in, c);
  // The logarithmic coarse levels are harmful here (docs/performance.md).
  static_cast<SolverSettings&>(c) = assemble_solver(in, std::nullopt);
  c.h0_relaxation = in.real("solver.h0_relaxation");
  c.fmg_cycles = in.integer("solver.fmg_cycles");
  c.fallback_update = in.get<bool>("solver.fallback_update");
  return c;
}

nlohmann::json rolling_parameters_json(const RollingConfig& c) {
  using nlohmann::json;
  json j;
  j["case"] = {
      {"M", c.M}, {"L", c.L}, {"D", c.D}, {"lambda_bar", c.lambda_bar}, {"alpha_bar", c.alpha_bar}};
  if (c.physical) {
    const RollingPhysical& p = *c.physical;
    j["physical"] = {{"Rx", p.Rx_m},        {"Ry", p.Ry_m},
                     {"load", p.load_N},    {"u1", p.u1_m_s},
                     {"u2", p.u2_m_s},      {"reduced_modulus", p.reduced_modulus_Pa},
                     {"eta0", p.eta0_Pa_s}, {"alpha", p.alpha_per_Pa}};
    const double um = 0.5 * (p.u1_m_s + p.u2_m_s);
    j["scales"] = {{"a_m", p.a_m},
                   {"ph_Pa", p.ph_Pa},
                   {"U", p.U},
                   {"W", p.W},
                   {"slide_to_roll", (p.u1_m_s - p.u2_m_s) / um}};
  }
  j["lubricant"] = lubricant_json(c.lubricant);
  j["body"] = {{"elastic", c.elastic}};
  j["grid"] = {{"points", c.grid_points},
               {"x_min", c.x_min},
               {"x_max", c.x_max},
               {"y_min", c.y_min},
               {"y_max", c.y_max}};
  j["solver"] = solver_settings_json(c);
  j["solver"]["h0_relaxation"] = c.h0_relaxation;
  j["solver"]["fmg_cycles"] = c.fmg_cycles;
  j["solver"]["fallback_update"] = c.fallback_update;
  return j;
}

}  // namespace ehlsim
