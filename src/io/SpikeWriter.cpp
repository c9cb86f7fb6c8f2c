#include "io/SpikeWriter.hpp"

#include <fmt/format.h>

#include <optional>
#include <stdexcept>

namespace ehlsim {

void SpikeSeriesWriter::write(const SpikeSample& s, double V_s) {
  csv_.append(fmt::format("{:.10g},{:.10g},{:.10g},{:.10g},{:.10g},{:.10g},{:.10g}", s.T, s.R_s,
                          s.P_s, V_s, s.A_dry, s.X_s, s.P_xs));
}

namespace {
std::optional<TimedValue> radius_at(const std::optional<SpikeSample>& s) {
  if (!s) return std::nullopt;
  return TimedValue{s->T, s->R_s};
}
}  // namespace

void SpikeSeriesWriter::append(const SpikeSample& next) {
  if (current_) {
    write(*current_, rate_at(radius_at(previous_), {current_->T, current_->R_s}, radius_at(next)));
    previous_ = current_;
  }
  current_ = next;
}

void SpikeSeriesWriter::resume_after(const SpikeSample& sample) {
  if (current_ || rows() > 0)
    throw std::logic_error("SpikeSeriesWriter::resume_after: rows were already added");
  previous_ = sample;
}

void SpikeSeriesWriter::commit() {
  if (current_) {
    write(*current_, rate_at(radius_at(previous_), {current_->T, current_->R_s}, std::nullopt));
    current_.reset();
  }
  csv_.commit();
}

void ProfileWriter::append(double T, const Profile& profile) {
  for (std::size_t k = 0; k < profile.size(); ++k) {
    csv_.append(fmt::format("{:.10g},{:.10g},{:.10g}", T, profile.position[k], profile.value[k]));
  }
}

SpikeOutput::SpikeOutput(const std::filesystem::path& directory, const ImpactConfig& config)
    : settings_(config.spike),
      order_(Grid2D(config.grid_points, config.half_width)),
      dry_(config.Delta0, config.V0) {
  std::filesystem::create_directories(directory);
  series_.emplace(directory / kFile);
}

void SpikeOutput::on_step(const StepRecord& record, const Field& P, const Field& /*H*/,
                          bool /*snapshot*/) {
  series_->append(spike_sample(record.T, analyze_spike(order_, P.span(), settings_), dry_));
}

void SpikeOutput::resume_after(double T, const Field& P) {
  series_->resume_after(spike_sample(T, analyze_spike(order_, P.span(), settings_), dry_));
}

void SpikeOutput::on_finish(const RunSummary& /*summary*/) { series_->commit(); }

}  // namespace ehlsim
