#pragma once
// SIGINT, SIGTERM and SIGHUP as a request to stop: while an InterruptGuard
// lives, these signals only set a flag that the run checks once per time step
// (StopOnSignal), so that it can write a checkpoint, remove its partial files
// and exit with 128 + the signal.  SIGXFSZ (a file beyond ulimit -f) is
// ignored, so that the write fails with EFBIG and is reported like a full disk.
#include <array>
#include <csignal>
#include <stdexcept>
#include <string>
#include <string_view>

#include "impact/ImpactObserver.hpp"

namespace ehlsim {

/// Exit code of a run stopped by `signal_number`: 128 + the signal, as shells do.
[[nodiscard]] int exit_code_for_signal(int signal_number);

/// "SIGINT", "SIGTERM", "SIGSEGV", ... ("signal N" for a number without a name).
[[nodiscard]] std::string signal_name(int signal_number);

class InterruptGuard {
 public:
  /// Installs the handlers (without SA_RESTART: a blocking waitpid returns
  /// EINTR) and clears the flag.
  InterruptGuard();
  /// Restores the handlers that were there before (unless held).
  ~InterruptGuard();
  InterruptGuard(const InterruptGuard&) = delete;
  InterruptGuard& operator=(const InterruptGuard&) = delete;

  /// The first of the signals received since construction, 0 while none.
  [[nodiscard]] static int received();

  /// Ignores the handled signals (SIGINT, SIGTERM, SIGHUP, SIGXFSZ) for the
  /// rest of the process (in every thread: a disposition is the process's),
  /// and the destructor no longer restores them.  Once a command has ended,
  /// its outcome is on disk; a signal in the moments left before the exit
  /// (exit handlers running) must not end the process with 128 + the signal
  /// for a run that was published.
  void hold_until_exit();

 private:
  static constexpr std::array<int, 4> kHandled = {SIGINT, SIGTERM, SIGHUP, SIGXFSZ};
  std::array<struct sigaction, kHandled.size()> previous_{};
  bool held_ = false;
};

/// Thrown by RunDirectory::publish when a signal came before the new contents
/// replaced the target: the target was left as it was.
class PublishInterrupted : public std::runtime_error {
 public:
  explicit PublishInterrupted(int signal_number);
  int signal;
};

/// A test hook (docs/usage.md, "Test hooks"): when the environment variable
/// EHLSIM_TEST_STOP_AT equals `point`, the process stops itself with SIGSTOP
/// here, so that a test can look at the files at this exact point and send a
/// signal before it continues (SIGCONT).  Only ever delays the process.
void stop_here_for_tests(std::string_view point);

/// Asks the run to stop at the end of the current step once a signal came.
class StopOnSignal final : public ImpactObserver {
 public:
  [[nodiscard]] bool stop_requested() const override { return InterruptGuard::received() != 0; }
};

}  // namespace ehlsim
