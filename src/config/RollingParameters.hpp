#pragma once
// The keys of `ehlsim rolling`, declared once (default, range, doc) like the
// impact's (config/Parameters.hpp): they drive the TOML reader, --set, --help and
// the echo into run.json.  [lubricant] and [solver] are the keys both modes
// share (config/ParameterSet.hpp).
#include <filesystem>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "config/ParameterSet.hpp"
#include "rolling/RollingConfig.hpp"

namespace ehlsim {

[[nodiscard]] const ParameterSet& rolling_parameters();

/// Reads and validates a rolling case; throws ConfigError on bad input.
[[nodiscard]] RollingConfig load_rolling_config(const std::optional<std::filesystem::path>& file,
                                                const std::vector<std::string>& overrides);

/// The effective values of a rolling case, by section (derived values included).
[[nodiscard]] nlohmann::json rolling_parameters_json(const RollingConfig& config);

}  // namespace ehlsim
