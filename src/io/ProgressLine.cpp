#include "io/ProgressLine.hpp"

#include <fmt/format.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <utility>

#include "dynamics/DryHertz.hpp"

namespace ehlsim {

namespace {
constexpr double kSecondsPerMinute = 60.0;
constexpr double kSecondsPerHour = 3600.0;
constexpr const char* kClearLine = "\r\x1b[K";  ///< carriage return + ANSI erase to end of line
}  // namespace

double estimate_end_time(double T, double Delta, double dDelta_dT, double T_end, double Delta0,
                         double V0) {
  if (std::isfinite(T_end)) return std::max(T_end, T);
  const double duration = dry_contact_duration(V0);
  const double margin = kLiftOffMargin * duration;
  double estimate = 0.0;
  if (dDelta_dT > 0.0) {
    estimate = T + std::max(-Delta, 0.0) / dDelta_dT + margin;
  } else {
    estimate = std::max(Delta0, 0.0) / V0 + duration + margin;
  }
  return std::max(estimate, T + margin);
}

std::string format_duration(double seconds) {
  if (!std::isfinite(seconds) || seconds < 0.0) return "?";
  if (seconds < kSecondsPerMinute) return fmt::format("{:.1f}s", seconds);
  const auto total = static_cast<long>(std::lround(seconds));
  const long per_minute = static_cast<long>(kSecondsPerMinute);
  const long per_hour = static_cast<long>(kSecondsPerHour);
  if (seconds < kSecondsPerHour)
    return fmt::format("{}m{:02}s", total / per_minute, total % per_minute);
  return fmt::format("{}h{:02}m", total / per_hour, (total % per_hour) / per_minute);
}

StatusLine::StatusLine(bool enabled, std::FILE* stream)
    : enabled_(enabled && stream != nullptr),
      stream_(stream),
      terminal_(stream != nullptr && isatty(fileno(stream)) == 1),
      start_(std::chrono::steady_clock::now()) {}

StatusLine::~StatusLine() {
  if (enabled_) end_line();
}

double StatusLine::elapsed() const {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
}

void StatusLine::end_line() {
  if (printed_ && terminal_) std::fputc('\n', stream_);
  printed_ = false;
  std::fflush(stream_);
}

void StatusLine::print(double elapsed, bool done) {
  const std::string line = last_(elapsed, done);
  if (terminal_) {
    std::fprintf(stream_, "%s%s", kClearLine, line.c_str());
  } else {
    std::fprintf(stream_, "%s\n", line.c_str());
  }
  std::fflush(stream_);
  last_print_ = elapsed;
  pending_ = false;
  printed_ = true;
}

void StatusLine::update(Text text) {
  if (!enabled_) return;
  last_ = std::move(text);
  pending_ = true;
  const double now = elapsed();
  const double interval = terminal_ ? kTerminalInterval : kLogInterval;
  if (last_print_ < 0.0 || now - last_print_ >= interval) print(now, false);
}

void StatusLine::note(const std::string& line) {
  if (!enabled_) return;
  if (printed_ && terminal_) std::fputs(kClearLine, stream_);
  std::fprintf(stream_, "%s\n", line.c_str());
  printed_ = false;
  std::fflush(stream_);
  last_print_ = -1.0;  // the state again at its next update
}

void StatusLine::finish() {
  if (!enabled_) return;
  // In a log too when the last state was printed already: its "done" line
  // is how a reader of the log sees that the solve ended.
  if (last_ && (pending_ || printed_)) print(elapsed(), true);
  end_line();
}

ProgressLine::ProgressLine(bool enabled, double T_end, double Delta0, double V0, std::FILE* stream)
    : T_end_(T_end), Delta0_(Delta0), V0_(V0), line_(enabled, stream) {}

std::string ProgressLine::text(const StepRecord& r, double elapsed, bool done) const {
  if (done) {
    return fmt::format(
        "T {:.4f}  step {}  Delta {:.4f}  force {:.4g}  cycles {}  res {:.1e}  done in {}", r.T,
        r.step, r.Delta, r.force, r.cycles, r.residual, format_duration(elapsed));
  }
  const double T_est = estimate_end_time(r.T, r.Delta, r.dDelta_dT, T_end_, Delta0_, V0_);
  const double remaining = r.T > 0.0 ? elapsed * (T_est - r.T) / r.T : -1.0;
  const char* approx = std::isfinite(T_end_) ? "" : "~";
  return fmt::format(
      "T {:.4f}/{}{:.2f}  step {}  Delta {:.4f}  force {:.4g}  cycles {}  res {:.1e}  "
      "{}, {}{} left",
      r.T, approx, T_est, r.step, r.Delta, r.force, r.cycles, r.residual, format_duration(elapsed),
      approx, format_duration(remaining));
}

void ProgressLine::update(const StepRecord& record) {
  line_.update([this, record](double elapsed, bool done) { return text(record, elapsed, done); });
}

}  // namespace ehlsim
