#pragma once
// A run.json with only what `ehlsim spike` reads of it: the ball's start and
// the run's spike settings (each of them, as every impact run records them).
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "config/Parameters.hpp"

namespace ehlsim::testing {

/// That run.json, with `extra` merged into it (e.g. a spike setting changed).
inline std::string minimal_run_json(const nlohmann::json& extra = nlohmann::json::object()) {
  nlohmann::json run;
  run["parameters"]["time"] = {{"Delta0", 1.0}, {"V0", 1.0}};
  run["parameters"]["spike"] = effective_parameters_json(load_config(std::nullopt, {}))["spike"];
  run.merge_patch(extra);
  return run.dump();
}

}  // namespace ehlsim::testing
