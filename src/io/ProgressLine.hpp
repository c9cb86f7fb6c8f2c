#pragma once
// One updating status line on stderr while a run goes on (StatusLine), and
// the impact's line of it (ProgressLine):
//
//   T 2.6094/~4.54  step 223  Delta -1.0933  force 2.7  cycles 5  res 3.1e-09  1m02s, ~31s left
//
// On a terminal the line is rewritten in place ("\r" + clear to end of line)
// at most kTerminalInterval apart; when stderr is not a terminal a full line is
// printed at most kLogInterval apart.  finish() ends the line.
//
// The remaining wall time is elapsed * (T_est - T) / T, with the end-time
// estimate T_est of estimate_end_time().
#include <chrono>
#include <cstdio>
#include <functional>
#include <string>

#include "impact/ImpactObserver.hpp"

namespace ehlsim {

/// Lubrication delays lift-off (the paper's M = 100, L = 10 case: 4.37 vs 4.218);
/// the estimate adds this fraction of the dry contact duration.
inline constexpr double kLiftOffMargin = 0.1;

/// Estimated end time of a run after the step `last`:
///  - T_end when it is finite (T once past it);
///  - before the rebound: first dry contact Delta0 / V0 plus the dry contact
///    duration Tc = dry_contact_duration(V0) (3.2181 at V0 = 1) plus the
///    margin, (Delta0/V0 + Tc) + 0.1 Tc;
///  - during the rebound (dDelta/dT > 0): linear extrapolation of Delta back to
///    0, T + max(-Delta, 0) / (dDelta/dT), plus the margin 0.1 Tc (the ball
///    accelerates while the film still pushes, so this errs late);
///  - never earlier than T + the margin when the run is not finished.
[[nodiscard]] double estimate_end_time(double T, double Delta, double dDelta_dT, double T_end,
                                       double Delta0, double V0);

/// "12.3s", "4m05s", "2h03m".
[[nodiscard]] std::string format_duration(double seconds);

/// A status line that follows a run's state, shown at most every
/// kTerminalInterval on a terminal (rewritten in place) and kLogInterval
/// elsewhere (full lines): the first state, then the latest when the interval
/// has passed, and the last one at finish().
class StatusLine {
 public:
  static constexpr double kTerminalInterval = 0.2;  ///< s: about five updates per second
  static constexpr double kLogInterval = 10.0;      ///< s: when the stream is not a terminal

  /// The text of a state after `elapsed` seconds (`done`: the last, at finish()).
  using Text = std::function<std::string(double elapsed, bool done)>;

  /// Disabled (prints nothing) when `enabled` is false (--quiet).
  explicit StatusLine(bool enabled, std::FILE* stream = stderr);
  /// Ends an unfinished line on a terminal (a failed run).
  ~StatusLine();
  StatusLine(const StatusLine&) = delete;
  StatusLine& operator=(const StatusLine&) = delete;

  /// A new state, shown now if the interval has passed.
  void update(Text text);
  /// A line of its own, now (an event in the run); the status line goes on below it.
  void note(const std::string& line);
  /// Shows the last state (if not yet shown) as done, and ends the line.
  void finish();

 private:
  [[nodiscard]] double elapsed() const;
  void print(double elapsed, bool done);
  void end_line();

  bool enabled_;
  std::FILE* stream_;
  bool terminal_;
  std::chrono::steady_clock::time_point start_;
  double last_print_ = -1.0;  ///< elapsed seconds at the last print, < 0: never
  bool pending_ = false;      ///< a state that has not been shown yet
  bool printed_ = false;      ///< a line on a terminal that is not ended yet
  Text last_;
};

/// The impact's status line: time, step, Delta, force, cycles, residual,
/// elapsed and estimated remaining time.
class ProgressLine {
 public:
  /// Disabled (prints nothing) when `enabled` is false (--quiet).
  ProgressLine(bool enabled, double T_end, double Delta0, double V0, std::FILE* stream = stderr);

  void update(const StepRecord& record);
  /// Prints the last state (if not yet shown) and ends the line.
  void finish() { line_.finish(); }

  /// The text of the line for a record after `elapsed` seconds (`done`: the
  /// run has finished, no estimate).
  [[nodiscard]] std::string text(const StepRecord& record, double elapsed, bool done = false) const;

 private:
  double T_end_;
  double Delta0_;
  double V0_;
  StatusLine line_;
};

}  // namespace ehlsim
