#pragma once
// The run directory of `ehlsim rolling`:
//
//   fields.nc          P and H of the converged solution (one snapshot, the
//                      same layout as the impact's fields.nc)
//   profile_x.csv      X, P, H along Y = 0
//   profile_y.csv      Y, P, H along X = X(Hm), the column of the minimum film
//   convergence.csv    residual, force error, Hc and H0 after every cycle
//   run.json           parameters, results (Hc, Hm, Hc_moes, ...), wall time
//
// The files are written into the staging directory of a RunDirectory
// (io/RunDirectory.hpp), which the caller publishes: the run directory is a
// transaction, as the impact's is.
#include <filesystem>
#include <nlohmann/json.hpp>

#include "rolling/RollingConfig.hpp"
#include "rolling/RollingProblem.hpp"

namespace ehlsim {

/// The "results" object of run.json.
[[nodiscard]] nlohmann::json rolling_results_json(const RollingConfig& config,
                                                  const RollingResult& result);

/// Writes every file of the run into `directory` (the staging directory).
/// Throws std::runtime_error / std::filesystem::filesystem_error.
void write_rolling_run(const std::filesystem::path& directory, const RollingConfig& config,
                       const RollingResult& result, const nlohmann::json& invocation,
                       double wall_seconds);

}  // namespace ehlsim
