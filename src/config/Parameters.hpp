#pragma once
// The parameters of `ehlsim impact`: every input key of an impact run is
// declared once, in config/Parameters.cpp (dotted name, type, default, allowed
// range, one-line documentation; the machinery is config/ParameterSet.hpp's).
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

#include "config/ParameterSet.hpp"
#include "impact/ImpactConfig.hpp"

namespace ehlsim {

/// Most time steps a run may take: time.max_steps, time.T_end / time.dT, and
/// the default step cap of a run until lift-off (a start far away or slow,
/// e.g. time.V0 = 1e-9, would need billions of steps).
inline constexpr int kMaxTimeSteps = 10'000'000;
/// The range of time.V0 (unit: v0; the paper's is 1).  The dry contact's
/// largest radius grows as V0^(2/5): below 1e-6 it spans fewer than six
/// meshes of the finest grid allowed (4097^2) on the paper's domain, above 1e6
/// it needs a domain 250 times the paper's; far beyond them the run's
/// energy bounds (V0^2) leave the range of doubles (V0 = 1e300: "must be >
/// inf").
inline constexpr double kMinV0 = 1e-6;
inline constexpr double kMaxV0 = 1e6;

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

/// The TOML string of a spike filter (as in the input files).
[[nodiscard]] std::string_view spike_filter_text(SpikeFilter filter);

}  // namespace ehlsim
