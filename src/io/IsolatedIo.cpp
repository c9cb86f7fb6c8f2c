#include "io/IsolatedIo.hpp"

#include <fcntl.h>
#include <fmt/format.h>
#include <netcdf.h>
#include <poll.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <csignal>
#include <cstring>
#include <optional>
#include <stdexcept>
#include <string>
#include <system_error>

#include "config/SystemFailure.hpp"
#include "io/Interrupt.hpp"
#include "io/NetcdfStatus.hpp"

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
/// Bytes read from the child's pipe at a time: its messages are a line or
/// two, so one read (a page) takes them whole.
constexpr std::size_t kPipeChunk = 4096;
/// The child's exit codes.
constexpr int kChildReturned = 0;
constexpr int kChildThrew = 2;
/// The first byte the child sends: its task returned, or threw (the message
/// follows).  The parent trusts these, not the exit status alone: with SIGCHLD
/// ignored the kernel reaps the child, and its status is lost.
constexpr char kReturnedMark = 'R';
constexpr char kThrewMark = 'T';

/// The parent's view of the child: its pid, and the read end of a pipe whose
/// write end only the child holds: the child writes how its task ended into
/// it (kReturnedMark, or kThrewMark and the message), and it hangs up when
/// the child ends, however it ends.
struct Child {
  pid_t pid = -1;
  int pipe = -1;
};

enum class Wait { Ended, TimedOut, Interrupted, Failed };

/// Writes `text` whole into `fd`, as far as it can: the parent reads it.
void send_text(int fd, std::string_view text) {
  while (!text.empty()) {
    const ssize_t written = write(fd, text.data(), text.size());
    if (written < 0 && errno == EINTR) continue;
    if (written <= 0) return;
    text.remove_prefix(static_cast<std::size_t>(written));
  }
}

/// The child: `task`, with no output and no exit handlers of the parent's.
[[noreturn]] void run_child(pid_t parent, int pipe, const std::function<void()>& task) {
  // No orphan looping in HDF5 after the parent has gone (even by kill -9).
  if (prctl(PR_SET_PDEATHSIG, SIGKILL) != 0 || getppid() != parent) {
    send_text(pipe, fmt::format("{}the child process could not be tied to ehlsim's (prctl: {})",
                                kThrewMark, std::strerror(errno)));
    _exit(kChildThrew);
  }
  const int null = open("/dev/null", O_WRONLY | O_CLOEXEC);
  if (null >= 0) {
    dup2(null, STDOUT_FILENO);
    dup2(null, STDERR_FILENO);
  }
  std::string report(1, kThrewMark);
  try {
    task();
    report = std::string(1, kReturnedMark);
  } catch (const std::exception& e) {
    report += e.what();
  } catch (...) {
    report += "an exception that is not a std::exception";
  }
  send_text(pipe, report);
  _exit(report.front() == kReturnedMark ? kChildReturned : kChildThrew);
}

Child start_child(const std::filesystem::path& path, std::string_view action,
                  const std::function<void()>& task) {
  std::array<int, 2> pipe_ends{};
  const pid_t parent = getpid();
  // Out of descriptors or processes: the machine's failure, not the file's.
  if (pipe2(pipe_ends.data(), O_CLOEXEC) != 0) {
    throw SystemFailure(
        fmt::format("cannot {} '{}': pipe: {}", action, path.string(), std::strerror(errno)));
  }
  const pid_t pid = fork();
  if (pid == 0) {
    close(pipe_ends[0]);
    run_child(parent, pipe_ends[1], task);  // keeps pipe_ends[1] open until it ends
  }
  const int fork_error = errno;
  close(pipe_ends[1]);
  if (pid < 0) {
    close(pipe_ends[0]);
    throw SystemFailure(fmt::format("cannot {} '{}': fork (to do it in a child process): {}",
                                    action, path.string(), std::strerror(fork_error)));
  }
  return {pid, pipe_ends[0]};
}

/// Reads what the child sent into `text`; true when the pipe hung up (the
/// child has ended).
bool read_available(int pipe, std::string& text) {
  std::array<char, kPipeChunk> buffer{};
  const ssize_t got = read(pipe, buffer.data(), buffer.size());
  if (got > 0) text.append(buffer.data(), static_cast<std::size_t>(got));
  return got == 0 || (got < 0 && errno != EINTR && errno != EAGAIN);
}

/// Waits until the child's pipe hangs up (collecting what it sent in `text`),
/// the bound has passed or, when asked to stop for it, a signal of
/// io/Interrupt.hpp has come (poll returns EINTR); Failed (errno set) when
/// poll fails otherwise.
Wait wait_for(const Child& child, const ChildWait& how, std::string& text) {
  const auto start = std::chrono::steady_clock::now();
  for (;;) {
    if (how.stop_on_interrupt && InterruptGuard::received() != 0) return Wait::Interrupted;
    int slice = kWaitSliceMs;
    if (how.bound) {
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
          start + *how.bound - std::chrono::steady_clock::now());
      if (left.count() <= 0) return Wait::TimedOut;
      slice = static_cast<int>(std::min<long>(left.count(), kWaitSliceMs));
    }
    pollfd hangup{child.pipe, POLLIN, 0};
    const int ready = poll(&hangup, 1, slice);
    if (ready > 0 && read_available(child.pipe, text)) return Wait::Ended;
    if (ready < 0 && errno != EINTR) return Wait::Failed;
  }
}

/// The wait status of the child once it has ended; killed first unless it
/// ended by itself.  None when it cannot be waited for: with SIGCHLD ignored
/// the kernel reaps it.
std::optional<int> reap(const Child& child, bool kill_first) {
  if (kill_first) kill(child.pid, SIGKILL);
  int status = 0;
  while (waitpid(child.pid, &status, 0) < 0) {
    if (errno != EINTR) return std::nullopt;  // not ours to wait for any more
  }
  return status;
}

/// How a child that ended by itself ended, from what it sent and its wait
/// status (none: unknown).  A child that did not say how its task ended
/// crashed, whatever its status.
ChildOutcome outcome_of(std::optional<int> status, std::string text) {
  const auto exited_with = [&](int code) {
    return !status || (WIFEXITED(*status) && WEXITSTATUS(*status) == code);
  };
  if (text.starts_with(kReturnedMark) && exited_with(kChildReturned))
    return {ChildOutcome::End::Returned, ""};
  if (text.starts_with(kThrewMark) && exited_with(kChildThrew))
    return {ChildOutcome::End::Threw, text.substr(1)};
  if (!status) return {ChildOutcome::End::Crashed, "ended without a report"};
  if (WIFSIGNALED(*status)) return {ChildOutcome::End::Crashed, signal_name(WTERMSIG(*status))};
  // A sanitizer's report, or an _exit of the task's own.
  return {ChildOutcome::End::Crashed, fmt::format("exit status {}", WEXITSTATUS(*status))};
}

/// Initialises NetCDF (and HDF5, and the network libraries of its remote
/// access) in this process, once, so that the children it forks find them
/// ready: each child would otherwise do it again, which took some 40 ms a
/// child, as much as writing a snapshot of 257^2.  Throws as check_netcdf.
void initialise_netcdf(const std::filesystem::path& path, std::string_view action) {
  check_netcdf(nc_initialize(), action, path, "nc_initialize");
}

}  // namespace

ChildOutcome run_in_child(const std::filesystem::path& path, std::string_view action,
                          const std::function<void()>& task, const ChildWait& how) {
  const Child child = start_child(path, action, task);
  std::string text;
  const Wait end = wait_for(child, how, text);
  const int wait_error = errno;  // poll's, when end is Failed
  close(child.pipe);
  const std::optional<int> status = reap(child, end != Wait::Ended);
  switch (end) {
    case Wait::Ended:
      return outcome_of(status, std::move(text));
    case Wait::TimedOut:
      return {ChildOutcome::End::TimedOut, ""};
    case Wait::Interrupted:
      return {ChildOutcome::End::Interrupted, "", InterruptGuard::received()};
    case Wait::Failed:
      break;
  }
  throw std::runtime_error(
      fmt::format("cannot {} '{}': poll (waiting for the child process that does it): {}", action,
                  path.string(), std::strerror(wait_error)));
}

std::chrono::milliseconds pre_read_bound(std::uintmax_t bytes) {
  return kPreReadBase + kPreReadPerMiB * static_cast<long>((bytes + kMiB - 1) / kMiB);
}

void pre_read_in_child(const std::filesystem::path& path, std::string_view action,
                       const std::function<void()>& read, std::chrono::milliseconds bound) {
  initialise_netcdf(path, action);
  const ChildOutcome outcome = run_in_child(path, action, read, {bound, true});
  switch (outcome.end) {
    case ChildOutcome::End::Returned:
    case ChildOutcome::End::Threw:
      return;  // the caller's own read gives the same result, or the same error
    case ChildOutcome::End::Interrupted:
      throw PreReadInterrupted(outcome.signal);
    case ChildOutcome::End::TimedOut:
      throw std::runtime_error(fmt::format(
          "cannot {} '{}': the NetCDF/HDF5 library did not finish reading it in {:.3g} s (it "
          "loops for ever on some damaged files; the read was stopped): the file is damaged",
          action, path.string(), std::chrono::duration<double>(bound).count()));
    case ChildOutcome::End::Crashed:
      break;
  }
  throw std::runtime_error(
      fmt::format("cannot {} '{}': the NetCDF/HDF5 library crashed reading it ({}): the file "
                  "is damaged",
                  action, path.string(), outcome.detail));
}

void pre_read_in_child(const std::filesystem::path& path, std::string_view action,
                       const std::function<void()>& read) {
  std::error_code ec;
  const std::uintmax_t bytes = std::filesystem::file_size(path, ec);
  pre_read_in_child(path, action, read, pre_read_bound(ec ? 0 : bytes));
}

void write_in_child(const std::filesystem::path& path, std::string_view action,
                    const std::function<void()>& write) {
  initialise_netcdf(path, action);
  const ChildOutcome outcome = run_in_child(path, action, write, {std::nullopt, false});
  if (outcome.end == ChildOutcome::End::Returned) return;
  if (outcome.end == ChildOutcome::End::Threw) throw std::runtime_error(outcome.detail);
  // Crashed: neither bound nor signal stops a write.
  throw std::runtime_error(fmt::format(
      "cannot {} '{}': the NetCDF/HDF5 library crashed writing it ({}; HDF5 1.10.8 does when "
      "the last write of a file fails, e.g. on an I/O error of the disk)",
      action, path.string(), outcome.detail));
}

}  // namespace ehlsim
