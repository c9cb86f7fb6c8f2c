#pragma once
// The parameter registry: every input key of an impact run is declared once
// here (dotted name, type, default, allowed range, one-line documentation).
// The registry drives the TOML reader, the `--set key=value` overrides, the
// `--help` text and the echo of the effective values into run.json and fields.nc.
//
// Keys are "section.name"; in a TOML file they are written
//
//   [case]
//   M = 100
//
// and on the command line as `--set case.M=100` (the value in TOML syntax;
// a bare word is taken as a string, so `--set lubricant.viscosity=roelands`
// works without quotes).  Overrides are applied after the file, in order.
#include <filesystem>
#include <nlohmann/json.hpp>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "impact/ImpactConfig.hpp"

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

/// Grid sizes the solver accepts: 2^k + 1 between these bounds.
inline constexpr int kMinGridPoints = 9;
inline constexpr int kMaxGridPoints = 4097;
/// Most time steps a run may take: time.max_steps, time.T_end / time.dT, and
/// the default step cap of a run until lift-off (a start far away or slow,
/// e.g. time.V0 = 1e-9, would need billions of steps).
inline constexpr int kMaxTimeSteps = 10'000'000;
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
/// The range of time.V0 (unit: v0; the paper's is 1).  The dry contact's
/// largest radius grows as V0^(2/5): below 1e-6 it spans fewer than six
/// meshes of the finest grid allowed (4097^2) on the paper's domain, above 1e6
/// it needs a domain 250 times the paper's; far beyond them the run's
/// energy bounds (V0^2) leave the range of doubles (V0 = 1e300: "must be >
/// inf").
inline constexpr double kMinV0 = 1e-6;
inline constexpr double kMaxV0 = 1e6;
/// Where a `KEY=VALUE` override came from, as error messages name it.
inline constexpr std::string_view kOverrideOrigin = "--set";
/// Smallest coarsest multigrid level.
inline constexpr int kMinCoarsestPoints = 5;

/// The sections, in the order of --help and of the echo.
[[nodiscard]] const std::vector<SectionSpec>& parameter_sections();
/// Every key, grouped by section in the order of parameter_sections().
[[nodiscard]] const std::vector<ParameterSpec>& parameter_registry();
/// The spec of a dotted key, nullptr if there is none.
[[nodiscard]] const ParameterSpec* find_parameter(std::string_view key);

/// Reads the optional TOML file, applies the `key=value` overrides, validates
/// everything and returns a complete config: lambda_bar, alpha_bar, M and L all
/// filled (from [case] or from [physical]), the Roelands/Dowson-Higginson inputs
/// resolved.  time.dT stays 0 when not given (meaning: the mesh size) and
/// time.T_end stays +inf when not given (meaning: until lift-off).
/// Throws ConfigError on any bad input.
/// `origin` names where the overrides came from in the error messages.
[[nodiscard]] ImpactConfig load_config(const std::optional<std::filesystem::path>& file,
                                       const std::vector<std::string>& overrides,
                                       std::string_view origin = kOverrideOrigin);

/// The registry as text for --help: every key with its default, range and doc.
[[nodiscard]] std::string describe_parameters();

/// The effective values of a config, as nested objects by section
/// {"case": {"M": ..., ...}, "lubricant": {...}, ...}.  Derived values are
/// included: all of M, L, lambda_bar, alpha_bar; for a physical case the
/// reduced inputs under "physical" and the reference scales under "scales".
/// time.dT is the effective step (the mesh size when not given); time.T_end is
/// null when the run goes until lift-off.
[[nodiscard]] nlohmann::json effective_parameters_json(const ImpactConfig& config);

/// The time step the run uses: config.dT, or the mesh size when dT == 0.
[[nodiscard]] double effective_time_step(const ImpactConfig& config);

/// The TOML strings of the enumerations (as in the input files).
[[nodiscard]] std::string_view viscosity_model_text(ViscosityModel model);
[[nodiscard]] std::string_view density_model_text(DensityModel model);
[[nodiscard]] std::string_view cycle_type_text(CycleType cycle);
[[nodiscard]] std::string_view deformation_method_text(DeformationMethod method);
[[nodiscard]] std::string_view spike_filter_text(SpikeFilter filter);

}  // namespace ehlsim
