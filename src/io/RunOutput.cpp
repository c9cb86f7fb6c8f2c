#include "io/RunOutput.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <utility>

#include "config/Parameters.hpp"
#include "impact/ImpactProblem.hpp"
#include "io/AtomicFile.hpp"
#include "io/ProgramInfo.hpp"

namespace ehlsim {

namespace {

/// A step at T counts as "at" a requested snapshot time t when T >= t - this * max(1, |t|)
/// (time steps accumulate rounding errors).
constexpr double kSnapshotTimeTolerance = 1e-9;

/// T has reached t, up to the rounding of accumulated time steps.
bool at_or_after(double T, double t) {
  return T >= t - kSnapshotTimeTolerance * std::max(1.0, std::abs(t));
}

nlohmann::json number_or_null(double v) {
  return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr);
}

}  // namespace

RunOutput::RunOutput(std::filesystem::path directory, const ImpactConfig& config,
                     bool show_progress, nlohmann::json invocation)
    : directory_(std::move(directory)),
      config_(config),
      invocation_(std::move(invocation)),
      parameters_(effective_parameters_json(config)),
      grid_(config.grid_points, config.half_width),
      snapshot_times_(config.snapshot_times),
      start_(std::chrono::steady_clock::now()),
      progress_(show_progress, config.T_end, config.Delta0, config.V0) {
  std::sort(snapshot_times_.begin(), snapshot_times_.end());
  std::filesystem::create_directories(directory_);
  timeseries_ = std::make_unique<TimeSeriesWriter>(directory_ / kTimeSeriesFile);
  convergence_ = std::make_unique<CsvWriter>(directory_ / kConvergenceFile, kConvergenceHeader);
}

RunOutput::~RunOutput() = default;

void RunOutput::on_start(const Grid2D& grid) {
  grid_ = grid;
  fields_ = std::make_unique<FieldWriter>(directory_ / kFieldsFile, grid_, parameters_);
}

void RunOutput::on_step(const StepRecord& record, const Field& P, const Field& H, bool snapshot) {
  timeseries_->append(record);
  // output.snapshot_start delays the periodic snapshots only: the last step
  // (lift-off, where no pressure is left, or T_end) is always stored.
  const bool last_step = !(record.p_max > 0.0) ||
                         (std::isfinite(config_.T_end) && at_or_after(record.T, config_.T_end));
  bool store = snapshot && (at_or_after(record.T, config_.snapshot_start) || last_step);
  while (next_snapshot_time_ < snapshot_times_.size()) {
    const double t = snapshot_times_[next_snapshot_time_];
    if (!at_or_after(record.T, t)) break;
    store = true;
    ++next_snapshot_time_;
  }
  if (store) {
    if (!fields_) on_start(grid_);
    fields_->append(record.T, P, H);
  }
  progress_.update(record);
}

void RunOutput::on_cycle(const CycleRecord& r) {
  convergence_->append(fmt::format("{},{:.10g},{:.10g},{},{:.10g},{},{:.10g}", r.step, r.T, r.dt,
                                   r.attempt, r.damping, r.cycle, r.residual));
}

void RunOutput::resume_after(double T) {
  while (next_snapshot_time_ < snapshot_times_.size() &&
         at_or_after(T, snapshot_times_[next_snapshot_time_]))
    ++next_snapshot_time_;
}

double RunOutput::elapsed_seconds() const {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
}

std::size_t RunOutput::steps_written() const { return timeseries_ ? timeseries_->rows() : 0; }

std::size_t RunOutput::snapshots_written() const { return fields_ ? fields_->snapshots() : 0; }

nlohmann::json RunOutput::run_json(const RunSummary& s) const {
  using nlohmann::json;
  const double wall = elapsed_seconds();
  json j;
  j["program"] = program_json("impact");
  if (!invocation_.empty()) j["invocation"] = invocation_;
  j["parameters"] = parameters_;
  j["derived"] = {{"M", config_.M},
                  {"L", config_.L},
                  {"lambda_bar", config_.lambda_bar},
                  {"alpha_bar", config_.alpha_bar}};
  if (config_.physical) j["derived"]["scales"] = parameters_["scales"];
  j["grid"] = {{"points", grid_.n},
               {"half_width", grid_.half_width},
               {"h", grid_.h()},
               {"solved_on", is_mirror_symmetric(config_) ? "quadrant" : "full"}};
  j["dT"] = effective_time_step(config_);
  j["results"] = {{"steps", s.steps},
                  {"outcome", outcome_text(s.outcome)},
                  {"lifted_off", s.lifted_off},
                  {"T_final", s.T_final},
                  {"T_lift_off", number_or_null(s.T_lift_off)},
                  {"rebound_speed", number_or_null(s.rebound_speed)},
                  {"max_force", s.max_force},
                  {"T_max_force", s.T_max_force},
                  {"min_h_center", s.min_h_center},
                  {"T_min_h_center", s.T_min_h_center},
                  {"initial_force", s.initial_force},
                  {"impulse", s.impulse},
                  {"edge_impulse", s.edge_impulse},
                  {"initial_elastic_energy", s.initial_elastic_energy},
                  {"final_energy", number_or_null(s.final_energy)},
                  {"unconverged_steps", s.unconverged_steps},
                  {"retried_steps", s.retried_steps},
                  {"warnings", s.warnings}};
  j["wall_seconds"] = wall;
  j["solver_wall_seconds"] = s.wall_seconds;
  j["files"] = {{"timeseries", kTimeSeriesFile},   {"timeseries_rows", steps_written()},
                {"convergence", kConvergenceFile}, {"convergence_rows", convergence_->rows()},
                {"fields", kFieldsFile},           {"snapshots", snapshots_written()}};
  j["files"].update(extra_files_);
  return j;
}

void RunOutput::on_finish(const RunSummary& summary) {
  progress_.finish();
  if (!fields_) on_start(grid_);  // a run without steps still gets a (empty) fields file
  timeseries_->commit();
  convergence_->commit();
  fields_->commit();
  write_json_atomic(directory_ / kRunFile, run_json(summary));
  committed_ = true;
}

}  // namespace ehlsim
