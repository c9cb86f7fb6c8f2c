#include "io/MemoryGuard.hpp"

#include <fmt/format.h>

#include <cmath>
#include <fstream>
#include <sstream>
#include <string>

#include "config/Parameters.hpp"
#include "impact/ImpactProblem.hpp"
#include "io/FieldWriter.hpp"

namespace ehlsim {

namespace {

constexpr double kBytesPerMB = 1e6;
constexpr const char* kGivenLimit = "solver.memory_limit_mb";
/// Calibrated on this machine against the peak RSS (/usr/bin/time -v) of
/// short runs on 129^2, 257^2 and 513^2, quadrant and full domain
/// (docs/performance.md, "Memory"), rounded up:
/// the process before any grid is allocated ...
constexpr double kProcessBytes = 24e6;
/// ... per point of every multigrid level (23 doubles: the FAS fields, the
/// operator's coefficients, the FFT buffers and kernel spectrum) ...
constexpr double kBytesPerSolverPoint = 184.0;
/// ... and per point of the full grid (11 doubles: the unfolded P and H the
/// observers get, the spike analysis's P(R), the kernel tables).
constexpr double kBytesPerGridPoint = 88.0;
/// A checkpoint unfolds four full-grid fields.
constexpr double kCheckpointBytesPerGridPoint = 4 * sizeof(double);
/// FieldWriter holds up to kFieldBatchBytes of snapshots until it writes them
/// (before, NetCDF kept up to 16 MiB of chunks of each of P and H), and a
/// snapshot is compressed one full-grid field at a time.
constexpr double kHeldSnapshotBytes = static_cast<double>(kFieldBatchBytes);
constexpr double kCompressionBytesPerGridPoint = 2 * sizeof(double);
/// The dry-Hertz table: at most 2^19 levels of T, Delta and V
/// (analysis/SpikeAnalysis.cpp, kMaxDryContactSteps).
constexpr double kDryTableBytes = 3.0 * sizeof(double) * (1 << 19);

/// The rolling contact (docs/performance.md, "Memory"): per point of the full
/// grid, 4 doubles (the start of a stage and its best iterate, kept for its
/// retries; the result's P and H) ...
constexpr double kRollingBytesPerGridPoint = 4 * sizeof(double);
/// ... and per point of every multigrid level, fitted to the peak RSS
/// (/usr/bin/time -f %M) of `ehlsim rolling` on 129^2 to 1025^2 above the
/// process, the full-grid arrays and the compression buffers: 171 bytes on
/// 1025^2 (306.3 MB), 157 on 513^2 (89.5 MB), rounded up to 22 doubles
/// (the chunk-cache constant, unused by one snapshot, adds a margin).
constexpr double kRollingBytesPerSolverPoint = 176.0;

/// Points of all multigrid levels, as ReynoldsHierarchy builds them: the
/// quadrant of each level when `quadrant` (a mirror-symmetric impact),
/// coarsened to solver.coarsest_points.
double solver_points(const SolverSettings& s, int grid_points, bool quadrant) {
  double points = 0.0;
  for (int n = grid_points;; n = (n + 1) / 2) {
    const double side = quadrant ? (n + 1) / 2 : n;
    points += side * side;
    if (n <= s.coarsest_points || n < kMinCoarsestPoints) break;
  }
  return points;
}

/// The held snapshots and one compressed full-grid field of P and H.
double output_bytes(double grid_points) {
  return kHeldSnapshotBytes + kCompressionBytesPerGridPoint * grid_points;
}

}  // namespace

MemoryEstimate estimate_run_memory(const ImpactConfig& c) {
  const double grid_points = static_cast<double>(c.grid_points) * c.grid_points;
  MemoryEstimate e;
  e.process_mb = kProcessBytes / kBytesPerMB;
  e.solver_mb =
      kBytesPerSolverPoint * solver_points(c, c.grid_points, is_mirror_symmetric(c)) / kBytesPerMB;
  const double checkpoint = c.checkpoint_every > 0 ? kCheckpointBytesPerGridPoint : 0.0;
  e.grid_mb = (kBytesPerGridPoint + checkpoint) * grid_points / kBytesPerMB;
  e.output_mb = (output_bytes(grid_points) + kDryTableBytes) / kBytesPerMB;
  return e;
}

MemoryEstimate estimate_rolling_memory(const RollingConfig& c) {
  const double grid_points = static_cast<double>(c.grid_points) * c.grid_points;
  MemoryEstimate e;
  e.process_mb = kProcessBytes / kBytesPerMB;
  // The rolling contact has no mirror symmetry: every level is the full grid.
  e.solver_mb = kRollingBytesPerSolverPoint * solver_points(c, c.grid_points, false) / kBytesPerMB;
  e.grid_mb = kRollingBytesPerGridPoint * grid_points / kBytesPerMB;
  e.output_mb = output_bytes(grid_points) / kBytesPerMB;
  return e;
}

std::optional<double> available_memory_mb() {
  std::ifstream meminfo("/proc/meminfo");
  std::string line;
  while (std::getline(meminfo, line)) {
    std::istringstream fields(line);
    std::string name;
    double kilobytes = 0.0;
    if (fields >> name >> kilobytes && name == "MemAvailable:")
      return kilobytes * 1024 / kBytesPerMB;
  }
  return std::nullopt;
}

MemoryBudget check_memory(const MemoryEstimate& estimate, double given_limit_mb, int grid_points,
                          std::optional<double> available_mb) {
  MemoryBudget b;
  b.estimate = estimate;
  const bool given = given_limit_mb > 0.0;
  if (given) {
    b.limit_mb = given_limit_mb;
    b.limit_source = kGivenLimit;
  } else if (available_mb) {
    b.limit_mb = *available_mb;
    b.limit_source = "MemAvailable";
  } else {
    return b;  // no limit known: nothing to check against
  }
  const double need = b.estimate.total_mb();
  if (need <= b.limit_mb) return b;
  const std::string limit =
      given ? fmt::format("the limit solver.memory_limit_mb = {:g}", b.limit_mb)
            : fmt::format(
                  "the {:.0f} MB this machine has available (MemAvailable in /proc/meminfo; "
                  "solver.memory_limit_mb sets another limit)",
                  b.limit_mb);
  throw ConfigError(
      fmt::format("grid.points = {}: the run needs about {:.0f} MB of memory (estimate), more "
                  "than {}: use fewer grid.points{}",
                  grid_points, need, limit, given ? ", or raise solver.memory_limit_mb" : ""),
      "grid.points");
}

MemoryBudget check_run_memory(const ImpactConfig& c, std::optional<double> available_mb) {
  return check_memory(estimate_run_memory(c), c.memory_limit_mb, c.grid_points, available_mb);
}

MemoryBudget check_run_memory(const RollingConfig& c, std::optional<double> available_mb) {
  return check_memory(estimate_rolling_memory(c), c.memory_limit_mb, c.grid_points, available_mb);
}

nlohmann::json memory_json(const MemoryBudget& b) {
  const auto mb = [](double v) { return std::round(v * 10.0) / 10.0; };
  nlohmann::json j = {{"estimate_mb", mb(b.estimate.total_mb())},
                      {"parts_mb",
                       {{"process", mb(b.estimate.process_mb)},
                        {"solver", mb(b.estimate.solver_mb)},
                        {"grid", mb(b.estimate.grid_mb)},
                        {"output", mb(b.estimate.output_mb)}}}};
  // The available memory changes from run to run: it is not recorded, so
  // that run.json depends on the input only (docs/usage.md, "Reproducibility").
  const bool given = b.limit_source == kGivenLimit;
  j["limit_mb"] = given ? nlohmann::json(b.limit_mb) : nlohmann::json(nullptr);
  j["limit_source"] =
      b.limit_source.empty() ? nlohmann::json(nullptr) : nlohmann::json(b.limit_source);
  return j;
}

}  // namespace ehlsim
