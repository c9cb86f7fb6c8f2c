#include "io/SpikeWriter.hpp"

#include <cmath>
#include <limits>

#include <fmt/format.h>

namespace ehlsim {

void SpikeSeriesWriter::write(const SpikeSample& s, double V_s) {
  csv_.append(fmt::format("{:.10g},{:.10g},{:.10g},{:.10g},{:.10g},{:.10g},{:.10g}", s.T, s.R_s,
                          s.P_s, V_s, s.A_dry, s.X_s, s.P_xs));
}

void SpikeSeriesWriter::append(const SpikeSample& next) {
  if (current_) {
    const SpikeSample& c = *current_;
    const double V_s = previous_ ? three_point_derivative(previous_->T, c.T, next.T, previous_->R_s,
                                                          c.R_s, next.R_s)
                                 : (next.R_s - c.R_s) / (next.T - c.T);
    write(c, V_s);
    previous_ = current_;
  }
  current_ = next;
}

void SpikeSeriesWriter::commit() {
  if (current_) {
    const SpikeSample& c = *current_;
    const double V_s = previous_ ? (c.R_s - previous_->R_s) / (c.T - previous_->T)
                                 : std::numeric_limits<double>::quiet_NaN();
    write(c, V_s);
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
      grid_(config.grid_points, config.half_width),
      dry_(config.Delta0, config.V0) {
  std::filesystem::create_directories(directory);
  series_.emplace(directory / kFile);
}

void SpikeOutput::on_step(const StepRecord& record, const Field& P, const Field& /*H*/,
                          bool /*snapshot*/) {
  series_->append(spike_sample(record.T, analyze_spike(grid_, P.span(), settings_), dry_));
}

void SpikeOutput::on_finish(const RunSummary& /*summary*/) { series_->commit(); }

}  // namespace ehlsim
