#include "io/IsolatedRead.hpp"

#include <fcntl.h>
#include <fmt/format.h>
#include <poll.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <csignal>
#include <cstring>
#include <stdexcept>
#include <string>
#include <system_error>

#include "io/Interrupt.hpp"

namespace ehlsim {

namespace {

/// The bound of a pre-read: kPreReadBase + kPreReadPerMiB per MiB of the
/// file.  A valid file takes a few milliseconds per MiB (measured on the
/// loaded 2-core machine: a 2.1 MB checkpoint of 257^2 in 13-22 ms, a 47 MB
/// fields.nc of 89 snapshots of 257^2, every snapshot read, in 0.11-0.15 s);
/// the bound allows some 70 times that per MiB, and 30 s more, so that a
/// loaded machine or a slow disk does not turn a good file into a "hang".
/// HDF5's loops on damaged metadata never end: a generous bound costs nothing
/// but the wait on such a file.
constexpr std::chrono::seconds kPreReadBase{30};
constexpr std::chrono::milliseconds kPreReadPerMiB{200};
constexpr std::uintmax_t kMiB = 1024 * 1024;
/// The longest single wait for the child: a signal handled on another thread
/// (OpenMP's, idle) does not interrupt this thread's poll, and is seen after
/// at most this long.
constexpr int kWaitSliceMs = 100;
/// The child's exit codes.
constexpr int kChildRead = 0;
constexpr int kChildFailed = 2;

/// The parent's view of the child: its pid, and the read end of a pipe whose
/// write end only the child holds, so that the pipe hangs up when the child
/// ends, however it ends.
struct Child {
  pid_t pid = -1;
  int hangup = -1;
};

enum class Wait { Ended, TimedOut, Interrupted, Failed };

/// The child: `read`, with no output and no exit handlers of the parent's.
[[noreturn]] void run_child(pid_t parent, const std::function<void()>& read) {
  // No orphan looping in HDF5 after the parent has gone (even by kill -9).
  if (prctl(PR_SET_PDEATHSIG, SIGKILL) != 0 || getppid() != parent) _exit(kChildFailed);
  const int null = open("/dev/null", O_WRONLY | O_CLOEXEC);
  if (null >= 0) {
    dup2(null, STDOUT_FILENO);
    dup2(null, STDERR_FILENO);
  }
  int code = kChildFailed;
  try {
    read();
    code = kChildRead;
  } catch (...) {
    // The parent reads the file again and reports this error itself.
  }
  _exit(code);
}

Child start_child(const std::filesystem::path& path, std::string_view action,
                  const std::function<void()>& read) {
  std::array<int, 2> pipe_ends{};
  const pid_t parent = getpid();
  if (pipe2(pipe_ends.data(), O_CLOEXEC) != 0) {
    throw std::runtime_error(
        fmt::format("cannot {} '{}': pipe: {}", action, path.string(), std::strerror(errno)));
  }
  const pid_t pid = fork();
  if (pid == 0) {
    close(pipe_ends[0]);
    run_child(parent, read);  // keeps pipe_ends[1] open until it ends
  }
  const int fork_error = errno;
  close(pipe_ends[1]);
  if (pid < 0) {
    close(pipe_ends[0]);
    throw std::runtime_error(
        fmt::format("cannot {} '{}': fork (to read it in a child process first): {}", action,
                    path.string(), std::strerror(fork_error)));
  }
  return {pid, pipe_ends[0]};
}

/// Waits until the child's pipe hangs up, `bound` has passed or a signal of
/// io/Interrupt.hpp has come (poll returns EINTR); Failed (errno set) when
/// poll fails otherwise.
Wait wait_for(const Child& child, std::chrono::milliseconds bound) {
  const auto deadline = std::chrono::steady_clock::now() + bound;
  for (;;) {
    if (InterruptGuard::received() != 0) return Wait::Interrupted;
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
        deadline - std::chrono::steady_clock::now());
    if (left.count() <= 0) return Wait::TimedOut;
    pollfd hangup{child.hangup, POLLIN, 0};
    const int ready =
        poll(&hangup, 1, static_cast<int>(std::min<long>(left.count(), kWaitSliceMs)));
    if (ready > 0) return Wait::Ended;
    if (ready < 0 && errno != EINTR) return Wait::Failed;
  }
}

/// The wait status of the child once it has ended; killed first unless it
/// ended by itself.  0 (a read) when it cannot be waited for: with SIGCHLD
/// ignored the kernel reaps it, and the caller's own read decides.
int reap(const Child& child, bool kill_first) {
  if (kill_first) kill(child.pid, SIGKILL);
  int status = 0;
  while (waitpid(child.pid, &status, 0) < 0) {
    if (errno != EINTR) return 0;  // not ours to wait for any more: nothing to report
  }
  return status;
}

/// "SIGSEGV", or "exit status 1" for a child that ended otherwise (a
/// sanitizer's report); "" for a child that ended as the read does.
std::string abnormal_end(int status) {
  if (WIFSIGNALED(status)) return signal_name(WTERMSIG(status));
  const int code = WIFEXITED(status) ? WEXITSTATUS(status) : kChildFailed;
  if (code == kChildRead || code == kChildFailed) return "";
  return fmt::format("exit status {}", code);
}

}  // namespace

std::chrono::milliseconds pre_read_bound(std::uintmax_t bytes) {
  return kPreReadBase + kPreReadPerMiB * static_cast<long>((bytes + kMiB - 1) / kMiB);
}

void pre_read_in_child(const std::filesystem::path& path, std::string_view action,
                       const std::function<void()>& read, std::chrono::milliseconds bound) {
  const Child child = start_child(path, action, read);
  const Wait end = wait_for(child, bound);
  const int wait_error = errno;  // poll's, when end is Failed
  close(child.hangup);
  const int status = reap(child, end != Wait::Ended);
  if (end == Wait::Interrupted) throw PreReadInterrupted(InterruptGuard::received());
  if (end == Wait::Failed) {
    throw std::runtime_error(
        fmt::format("cannot {} '{}': poll (waiting for the child process that reads it first): {}",
                    action, path.string(), std::strerror(wait_error)));
  }
  if (end == Wait::TimedOut) {
    throw std::runtime_error(fmt::format(
        "cannot {} '{}': the NetCDF/HDF5 library did not finish reading it in {:.3g} s (it loops "
        "for ever on some damaged files; the read was stopped): the file is damaged",
        action, path.string(), std::chrono::duration<double>(bound).count()));
  }
  if (const std::string how = abnormal_end(status); !how.empty()) {
    throw std::runtime_error(
        fmt::format("cannot {} '{}': the NetCDF/HDF5 library crashed reading it ({}): the file "
                    "is damaged",
                    action, path.string(), how));
  }
}

void pre_read_in_child(const std::filesystem::path& path, std::string_view action,
                       const std::function<void()>& read) {
  std::error_code ec;
  const std::uintmax_t bytes = std::filesystem::file_size(path, ec);
  pre_read_in_child(path, action, read, pre_read_bound(ec ? 0 : bytes));
}

}  // namespace ehlsim
