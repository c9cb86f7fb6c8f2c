#pragma once
// The memory guard of `ehlsim impact` and `ehlsim rolling`: an estimate of
// the peak resident memory of a run, made from its configuration before
// anything big is allocated, and the refusal (exit 2) of a run that would not
// fit (docs/usage.md, "Memory guard"; the calibration: docs/performance.md).
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "impact/ImpactConfig.hpp"
#include "rolling/RollingConfig.hpp"

namespace ehlsim {

/// The peak resident memory of a run, by what holds it [MB = 1e6 bytes].
struct MemoryEstimate {
  double process_mb = 0.0;  ///< program, libraries (HDF5, FFTW, OpenMP), small tables
  double solver_mb = 0.0;   ///< multigrid levels: fields, operators, FFT buffers, kernels
  double grid_mb = 0.0;     ///< full-grid arrays: unfolded fields, spike analysis, checkpoint
  double output_mb = 0.0;   ///< held snapshots and compression buffers, dry-Hertz table
  [[nodiscard]] double total_mb() const { return process_mb + solver_mb + grid_mb + output_mb; }
};

[[nodiscard]] MemoryEstimate estimate_run_memory(const ImpactConfig& config);
/// The same parts for a steady rolling contact (always on the full grid).
[[nodiscard]] MemoryEstimate estimate_rolling_memory(const RollingConfig& config);

/// MemAvailable of /proc/meminfo [MB]; nullopt when it cannot be read.
[[nodiscard]] std::optional<double> available_memory_mb();

/// The estimate and the limit it was checked against.
struct MemoryBudget {
  MemoryEstimate estimate;
  double limit_mb = 0.0;
  std::string limit_source;  ///< "solver.memory_limit_mb" or "MemAvailable"
};

/// Throws ConfigError (key grid.points) when `estimate` exceeds
/// `given_limit_mb` (solver.memory_limit_mb; 0: not given), or, when that is
/// not given, the machine's available memory.  `available_mb` is
/// available_memory_mb() (a parameter for tests); without it only a given
/// limit is checked.  `grid_points` names the run in the message.
[[nodiscard]] MemoryBudget check_memory(const MemoryEstimate& estimate, double given_limit_mb,
                                        int grid_points, std::optional<double> available_mb);

/// check_memory of the run's estimate and solver.memory_limit_mb.
[[nodiscard]] MemoryBudget check_run_memory(const ImpactConfig& config,
                                            std::optional<double> available_mb);
[[nodiscard]] MemoryBudget check_run_memory(const RollingConfig& config,
                                            std::optional<double> available_mb);

/// {"estimate_mb", "limit_mb", "limit_source", "parts_mb": {...}} for run.json;
/// limit_mb is null unless solver.memory_limit_mb gave it (the available
/// memory would make run.json differ between runs of the same input).
[[nodiscard]] nlohmann::json memory_json(const MemoryBudget& budget);

}  // namespace ehlsim
