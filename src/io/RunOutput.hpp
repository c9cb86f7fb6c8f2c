#pragma once
// The output of one impact run, as an ImpactObserver: in the run directory
//
//   timeseries.csv  one row per time step
//   convergence.csv one row per multigrid cycle of every attempt of every step
//   fields.nc       P and H snapshots: every output.snapshot_every steps (the
//                   solver's `snapshot` flag) from output.snapshot_start on,
//                   the first step at or after each time in
//                   output.snapshot_times, and the last step
//   run.json        effective parameters, program version, grid, time step,
//                   results (lift-off, rebound speed, max force, ...), wall time
//
// plus the progress line on stderr.  Files are written as "<name>.part" and
// renamed when the run finishes (on_finish); if the run fails (the observer is
// destroyed without on_finish) the partial files are removed.  run.json is
// renamed last, so its presence marks a complete run.
#include <chrono>
#include <cstddef>
#include <filesystem>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <string_view>
#include <vector>

#include "impact/ImpactConfig.hpp"
#include "impact/ImpactObserver.hpp"
#include "io/CsvWriter.hpp"
#include "io/FieldWriter.hpp"
#include "io/ProgressLine.hpp"
#include "io/TimeSeriesWriter.hpp"

namespace ehlsim {

class RunOutput final : public ImpactObserver {
 public:
  static constexpr std::string_view kTimeSeriesFile = "timeseries.csv";
  static constexpr std::string_view kConvergenceFile = "convergence.csv";
  static constexpr std::string_view kConvergenceHeader = "step,T,dt,attempt,damping,cycle,residual";
  static constexpr std::string_view kFieldsFile = "fields.nc";
  static constexpr std::string_view kRunFile = "run.json";

  /// Creates the directory (and parents) if missing and opens the time series.
  /// `invocation` is recorded as is in run.json (e.g. config file, overrides).
  /// Throws std::runtime_error / std::filesystem::filesystem_error.
  RunOutput(std::filesystem::path directory, const ImpactConfig& config, bool show_progress,
            nlohmann::json invocation = nlohmann::json::object());
  ~RunOutput() override;
  RunOutput(const RunOutput&) = delete;
  RunOutput& operator=(const RunOutput&) = delete;

  void on_start(const Grid2D& grid) override;
  void on_step(const StepRecord& record, const Field& P, const Field& H, bool snapshot) override;
  void on_cycle(const CycleRecord& record) override;
  void on_finish(const RunSummary& summary) override;
  /// A restart from the state after the step at T: the times of
  /// output.snapshot_times reached by then were stored by the run that wrote
  /// the checkpoint, and are not stored again.  Before the first step.
  void resume_after(double T);

  [[nodiscard]] const std::filesystem::path& directory() const { return directory_; }
  [[nodiscard]] bool committed() const { return committed_; }
  [[nodiscard]] std::size_t steps_written() const;
  /// Wall time since construction [s].
  [[nodiscard]] double elapsed_seconds() const;
  [[nodiscard]] std::size_t snapshots_written() const;
  /// Names a further file of the run directory in run.json's "files" (e.g.
  /// "spike": "spike.csv", written by another observer).
  void add_file(const std::string& key, std::string_view name) { extra_files_[key] = name; }
  /// The run.json document for a summary (what on_finish writes).
  [[nodiscard]] nlohmann::json run_json(const RunSummary& summary) const;

 private:
  std::filesystem::path directory_;
  ImpactConfig config_;
  nlohmann::json invocation_;
  nlohmann::json parameters_;
  nlohmann::json extra_files_ = nlohmann::json::object();
  Grid2D grid_;
  std::vector<double> snapshot_times_;  ///< sorted
  std::size_t next_snapshot_time_ = 0;
  std::chrono::steady_clock::time_point start_;
  std::unique_ptr<TimeSeriesWriter> timeseries_;
  std::unique_ptr<CsvWriter> convergence_;
  std::unique_ptr<FieldWriter> fields_;
  ProgressLine progress_;
  bool committed_ = false;
};

}  // namespace ehlsim
