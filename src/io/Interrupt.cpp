#include "io/Interrupt.hpp"

#include <fmt/format.h>

#include <cstdlib>
#include <cstring>

namespace ehlsim {

namespace {

constexpr int kExitSignalBase = 128;
constexpr const char* kTestStopVariable = "EHLSIM_TEST_STOP_AT";

// The one piece of global state: a signal handler can only talk through it.
volatile std::sig_atomic_t g_received = 0;

extern "C" void record_signal(int signal_number) {
  if (g_received == 0) g_received = signal_number;
}

struct sigaction action_with(void (*handler)(int)) {
  struct sigaction action {};
  action.sa_handler = handler;
  sigemptyset(&action.sa_mask);
  action.sa_flags = 0;  // no SA_RESTART: blocking calls return EINTR
  return action;
}

}  // namespace

int exit_code_for_signal(int signal_number) { return kExitSignalBase + signal_number; }

std::string signal_name(int signal_number) {
  const char* abbreviation = sigabbrev_np(signal_number);  // "INT", "SEGV", ...
  return abbreviation != nullptr ? fmt::format("SIG{}", abbreviation)
                                 : fmt::format("signal {}", signal_number);
}

InterruptGuard::InterruptGuard() {
  g_received = 0;
  const struct sigaction stop = action_with(record_signal);
  const struct sigaction ignore = action_with(SIG_IGN);
  for (std::size_t k = 0; k < kHandled.size(); ++k)
    sigaction(kHandled[k], kHandled[k] == SIGXFSZ ? &ignore : &stop, &previous_[k]);
}

InterruptGuard::~InterruptGuard() {
  if (held_) return;
  for (std::size_t k = 0; k < kHandled.size(); ++k) sigaction(kHandled[k], &previous_[k], nullptr);
}

int InterruptGuard::received() { return g_received; }

void InterruptGuard::hold_until_exit() {
  const struct sigaction ignore = action_with(SIG_IGN);
  for (const int signal_number : kHandled) sigaction(signal_number, &ignore, nullptr);
  held_ = true;
}

PublishInterrupted::PublishInterrupted(int signal_number)
    : std::runtime_error(
          fmt::format("interrupted by {} before publishing", signal_name(signal_number))),
      signal(signal_number) {}

void stop_here_for_tests(std::string_view point) {
  const char* wanted = std::getenv(kTestStopVariable);
  if (wanted != nullptr && point == wanted) std::raise(SIGSTOP);
}

}  // namespace ehlsim
