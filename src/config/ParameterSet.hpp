#pragma once
// The machinery every mode's configuration shares: a set of declared keys
// (ParameterSpec), read from an optional TOML file and `--set KEY=VALUE`
// overrides, validated against their declarations, and handed to the mode as
// typed Inputs (config/ParameterSet.cpp).  `ehlsim impact` and `ehlsim
// rolling` each declare their set once (config/Parameters.cpp,
// config/RollingParameters.cpp); the declarations that both modes have (the
// lubricant, the solids, the multigrid settings) are added by the shared
// add_*_parameters functions (config/SharedParameters.cpp).
#include <filesystem>
#include <initializer_list>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "grid/Grid.hpp"  // kMinGridPoints, kMaxGridPoints
#include "impact/Scaling.hpp"
#include "reynolds/SolverSettings.hpp"
#include "rheology/Lubricant.hpp"

namespace ehlsim {

/// A bad input: unknown key, wrong type, value out of range, inconsistent
/// combination, unreadable or malformed file.  what() is one line that names
/// the full dotted key, the value and what is allowed, e.g.
/// "case.M = -3: must be > 0 (case.toml:2:5)".
class ConfigError : public std::runtime_error {
 public:
  explicit ConfigError(const std::string& message, std::string key = {});
  /// The dotted key the error is about ("" for file-level errors).
  [[nodiscard]] const std::string& key() const noexcept { return key_; }

 private:
  std::string key_;
};

/// A user's input (a value, a key, an option's argument) as an error message
/// echoes it: in full up to kEchoMaxChars characters, else its start and
/// "... (N bytes)", so that a runaway value does not flood the terminal.
inline constexpr std::size_t kEchoMaxChars = 80;
[[nodiscard]] std::string echo_input(std::string_view text);

/// Why a nonzero number written too small for a double (1e-400), and one
/// beyond its range (1e400), is refused: the same words for every input.
[[nodiscard]] std::string double_underflow_reason();
[[nodiscard]] std::string double_overflow_reason();
/// Whether `value`, read from the number written as `literal` (1e-400),
/// is a 0 that the literal does not say: its mantissa has a nonzero digit.
[[nodiscard]] bool underflowed_to_zero(double value, std::string_view literal);

enum class ParameterType { Float, Int, Bool, Enum, FloatArray };

/// A parameter value as the registry stores it (defaults, validated inputs).
using ParameterValue = std::variant<bool, int, double, std::string, std::vector<double>>;

/// One end of an allowed interval.
struct Bound {
  double value = 0.0;
  bool inclusive = false;
};

struct ParameterSpec {
  std::string key;  ///< "section.name"
  ParameterType type = ParameterType::Float;
  std::optional<ParameterValue> default_value;  ///< none: optional input or derived
  std::string default_text;                     ///< shown by --help when there is no default value
  std::optional<Bound> lower;                   ///< Float, Int, FloatArray entries
  std::optional<Bound> upper;
  bool power_of_two_plus_one = false;  ///< Int: 2^k + 1
  bool allow_infinite = false;         ///< Float: +inf allowed
  std::vector<std::string> choices;    ///< Enum: the allowed strings
  std::string units;                   ///< physical units, "" if dimensionless
  std::string doc;                     ///< one line

  [[nodiscard]] std::string_view section() const;
  [[nodiscard]] std::string_view name() const;
  /// What is allowed, as in the error messages: "> 0", "in [0, 0.5]",
  /// "one of \"barus\", \"roelands\"", "2^k + 1 between 9 and 4097", ...
  [[nodiscard]] std::string allowed() const;
  /// The default as --help shows it (TOML syntax, or a description).
  [[nodiscard]] std::string default_description() const;
};

struct SectionSpec {
  std::string name;
  std::string doc;
};

/// Most relaxation sweeps before or after the coarse-grid correction.  A
/// signal is acted on between cycles, so one cycle must end in reasonable
/// time (solver.pre_sweeps = 2e9 ran on after SIGTERM); more sweeps never paid
/// (docs/performance.md: 5 + 3 cost more work than 3 + 2 on 1025^2).
inline constexpr int kMaxSweeps = 20;
/// The largest solver.tolerance.  The rolling contact stops when both the
/// residual and the force error are below it, and the impact's measure
/// starts a step at about 1e-2 (2.6e-2 on 257^2): above 1e-2 a run ends with
/// the load unbalanced by percents (rolling M = 100, L = 10 on 33^2: force
/// error 4.9 % at 0.1, 20 % at 1e300, both with exit 0).
inline constexpr double kMaxTolerance = 1e-2;
/// Where a `KEY=VALUE` override came from, as error messages name it.
inline constexpr std::string_view kOverrideOrigin = "--set";
/// Smallest coarsest multigrid level.
inline constexpr int kMinCoarsestPoints = 5;

/// The keys of one mode: its sections in --help order and their keys.
struct ParameterSet {
  std::vector<SectionSpec> sections;
  std::vector<ParameterSpec> specs;
  /// The first lines of the --help text of the parameters.
  std::string intro;
  /// The spec of a dotted key, nullptr if there is none.
  [[nodiscard]] const ParameterSpec* find(std::string_view key) const;
};

/// One validated input.
struct Given {
  ParameterValue value;
  std::string text;    ///< as written
  std::string origin;  ///< "file:line:col" or "--set"
};

/// Typed access to the validated inputs, falling back to the set's defaults.
class Inputs {
 public:
  using GivenMap = std::map<std::string, Given, std::less<>>;
  Inputs(GivenMap given, const ParameterSet& set) : given_(std::move(given)), set_(&set) {}

  [[nodiscard]] const Given* given(std::string_view key) const {
    const auto it = given_.find(key);
    return it == given_.end() ? nullptr : &it->second;
  }
  [[nodiscard]] bool has(std::string_view key) const { return given(key) != nullptr; }
  [[nodiscard]] bool any_in_section(std::string_view section) const;

  template <typename T>
  [[nodiscard]] T get(std::string_view key) const {
    if (const Given* g = given(key)) return std::get<T>(g->value);
    return std::get<T>(default_of(key));
  }
  [[nodiscard]] double real(std::string_view key) const { return get<double>(key); }
  [[nodiscard]] int integer(std::string_view key) const { return get<int>(key); }
  [[nodiscard]] std::optional<double> optional_real(std::string_view key) const {
    if (const Given* g = given(key)) return std::get<double>(g->value);
    return std::nullopt;
  }
  /// A value that is required in this context.
  [[nodiscard]] double required_real(const std::string& key, const std::string& why) const;
  /// Throws ConfigError "key = value: problem (origin)" for a given key.
  [[noreturn]] void fail(const std::string& key, const std::string& problem) const;

 private:
  [[nodiscard]] const ParameterValue& default_of(std::string_view key) const;
  GivenMap given_;
  const ParameterSet* set_;
};

/// Reads the optional TOML file, applies the overrides in order and validates
/// every key and value against `set`.  Throws ConfigError, naming a value's
/// place in the file, or `origin` for an override.
[[nodiscard]] Inputs read_inputs(const ParameterSet& set,
                                 const std::optional<std::filesystem::path>& file,
                                 const std::vector<std::string>& overrides,
                                 std::string_view origin = kOverrideOrigin);

/// The set as text for --help: every key with its default, range and doc.
[[nodiscard]] std::string describe_parameters(const ParameterSet& set);

// Declaring keys: one call per key (no default: std::nullopt, with the text
// --help shows instead).
/// No bound on that side of the interval.
inline constexpr std::optional<Bound> kUnbounded;
/// A key without a default value.
inline constexpr std::optional<double> kNoDefault;
[[nodiscard]] Bound above(double v);
[[nodiscard]] Bound at_least(double v);
[[nodiscard]] Bound at_most(double v);
[[nodiscard]] Bound below(double v);
[[nodiscard]] ParameterSpec real(std::string key, std::optional<double> def,
                                 std::string default_text, std::optional<Bound> lower,
                                 std::optional<Bound> upper, std::string units, std::string doc);
[[nodiscard]] ParameterSpec integer(std::string key, int def, std::optional<Bound> lower,
                                    std::optional<Bound> upper, bool power_of_two_plus_one,
                                    std::string doc);
[[nodiscard]] ParameterSpec boolean(std::string key, bool def, std::string doc);
[[nodiscard]] ParameterSpec choice(std::string key, std::string_view def,
                                   std::vector<std::string> choices, std::string doc);
[[nodiscard]] ParameterSpec real_array(std::string key, std::optional<Bound> lower,
                                       std::string doc);

// Declarations both modes share, each with the defaults of its mode.

/// physical.eta0 and physical.alpha: the lubricant of a case in SI units.
void add_physical_lubricant_parameters(std::vector<ParameterSpec>& specs);
/// body.elastic and grid.points (`default_points` per side).
void add_body_and_grid_points_parameters(std::vector<ParameterSpec>& specs, int default_points);
/// [lubricant]: the viscosity and density laws and their inputs.
void add_lubricant_parameters(std::vector<ParameterSpec>& specs);
/// The lubricant of validated [lubricant] inputs.  `alpha_bar` comes from the
/// case; `physical` holds ph*, eta0 and alpha [SI] when the case was given in
/// physical units (then the [lubricant] keys that repeat them are refused).
struct PhysicalLubricant {
  double ph_star_Pa = 0.0;
  double eta0_Pa_s = 0.0;
  double alpha_per_Pa = 0.0;
};
[[nodiscard]] Lubricant assemble_lubricant(const Inputs& in, double alpha_bar,
                                           const std::optional<PhysicalLubricant>& physical);
/// The Moes groups of a case must be numbers: M and lambda_bar finite and
/// > 0, L and alpha_bar finite and >= 0.  Inputs whose groups leave double
/// precision (case.M = 1e300: lambda_bar = 0) are bad input: fails naming
/// the [physical] section when there is one, else `load_key` (the [case] key
/// that set M) when M or lambda_bar is wrong, else `lubricant_key`.
void check_moes_groups(const Inputs& in, const MoesGroups& groups, const std::string& load_key,
                       const std::string& lubricant_key);

/// The groups of a case whose Roelands law was given its own pressure-viscosity
/// (lubricant.z or lubricant.alpha, which a [physical] section refuses): L and alpha_bar
/// are then the lubricant's, alpha ph* at p = 0, and a key of `L_keys` (the
/// [case] keys that set L) given as well is refused.  Otherwise `g` as it is.
/// `load_key` names the key that set M, for check_moes_groups.
[[nodiscard]] MoesGroups with_lubricant_L(const Inputs& in, const Lubricant& lub, MoesGroups g,
                                          std::initializer_list<const char*> L_keys,
                                          const std::string& load_key);

/// [solver]: the multigrid settings both modes have (SolverSettings), with
/// the defaults of the mode.  `tolerance_doc` and `max_cycles_doc` say what
/// convergence and a cycle limit mean in the mode.
void add_solver_parameters(std::vector<ParameterSpec>& specs, const SolverSettings& defaults,
                           const std::string& tolerance_doc, const std::string& max_cycles_doc);
/// The SolverSettings of validated [solver] inputs (checks coarsest_points
/// against grid.points and pre_sweeps + post_sweeps >= 1).
/// `auto_coarse_face_mean` is what solver.coarse_face_mean = "auto" gives
/// in the mode and case (std::nullopt: the finest grid's mean).
[[nodiscard]] SolverSettings assemble_solver(const Inputs& in,
                                             std::optional<FaceMean> auto_coarse_face_mean);
/// The TOML strings of the enumerations (as in the input files).
[[nodiscard]] std::string_view viscosity_model_text(ViscosityModel model);
[[nodiscard]] std::string_view density_model_text(DensityModel model);
[[nodiscard]] std::string_view cycle_type_text(CycleType cycle);
[[nodiscard]] std::string_view deformation_method_text(DeformationMethod method);
[[nodiscard]] std::string_view face_mean_text(FaceMean mean);

/// The echo of a lubricant's laws and inputs for run.json ([lubricant]).
[[nodiscard]] nlohmann::json lubricant_json(const Lubricant& lubricant);
/// The same on one line, for the case summary a run prints.
[[nodiscard]] std::string lubricant_text(const Lubricant& lubricant);

/// The echo of the SolverSettings for run.json.
[[nodiscard]] nlohmann::json solver_settings_json(const SolverSettings& settings);

}  // namespace ehlsim
