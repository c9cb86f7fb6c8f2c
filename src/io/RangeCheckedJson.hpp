#pragma once
// JSON read with every number checked against the range of a double: the
// parser reads 1e-400 as 0 without a word, and refused 1e400 without naming
// the key.  For the files a user may edit by hand (run.json).
#include <istream>
#include <nlohmann/json.hpp>
#include <string>

namespace ehlsim {

/// Parses `in`.  Throws ConfigError "cannot read '<name>': ..." for text
/// that is not JSON, and one naming the key path (parameters.spike.x,
/// output.snapshot_times[1]) and the number as written for a number that is
/// nonzero but too small for a double, or beyond its range.
[[nodiscard]] nlohmann::json parse_range_checked_json(std::istream& in, const std::string& name);

}  // namespace ehlsim
