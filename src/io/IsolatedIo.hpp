#pragma once
// NetCDF I/O that HDF5 1.10.8 (under NetCDF 4.9.0) may crash in runs in a
// child process, so that its crash becomes an error naming the file instead of
// the end of ehlsim (docs/validation.md, "Fuzzing and sanitizers" and "HDF5
// crashes when a write fails"):
//
// - reads of a file from outside this process (the checkpoint of `ehlsim
//   impact --restart`, the fields.nc of `ehlsim spike`): HDF5 crashes
//   (SIGSEGV in H5HG_read) or loops for ever (in H5HG's heap parser) on some
//   files damaged inside its metadata, which ehlsim cannot check before HDF5
//   reads it.  The child makes the very read the caller is about to make.
// - every write (checkpoint.nc, fields.nc): when the last write of nc_close
//   fails (an I/O error), H5Fclose fails and NetCDF's report of the objects
//   left open dereferences the file's freed root group (SIGSEGV in
//   H5G_rootof).  The child makes the write, and its error comes back as text.
#include <chrono>
#include <cstdint>
#include <exception>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <string_view>

namespace ehlsim {

/// How a task run in a child process (run_in_child) ended.
struct ChildOutcome {
  enum class End {
    Returned,     ///< the task returned
    Threw,        ///< the task threw: `detail` is the exception's what()
    Crashed,      ///< died of a signal, or ended otherwise: `detail` is "SIGSEGV", "exit status 1"
    TimedOut,     ///< ran out of its bound and was killed
    Interrupted,  ///< a signal of io/Interrupt.hpp reached this process; the child was killed
  };
  End end = End::Returned;
  std::string detail;
  int signal = 0;  ///< the signal that reached this process (Interrupted)
};

/// What this process does while the child runs.
struct ChildWait {
  /// Kill the child when it has run this long; none: wait until it ends.
  std::optional<std::chrono::milliseconds> bound;
  /// Kill the child when SIGINT, SIGTERM or SIGHUP reaches this process
  /// (io/Interrupt.hpp); otherwise wait on (a checkpoint written because of
  /// the signal must be complete).
  bool stop_on_interrupt = false;
};

/// Runs `task` in a child process (fork) and waits for it.  The child has no
/// output (stdout and stderr go to /dev/null), dies with this process, and
/// ends with _exit: no exit handler (HDF5's closes every open file) runs
/// there.  `task` must not use OpenMP: the child has none of the parent's
/// threads.  Throws SystemFailure (config/SystemFailure.hpp) "cannot <action>
/// '<path>': fork ...: <reason>" (or "pipe: ...") when the child cannot be
/// started.
[[nodiscard]] ChildOutcome run_in_child(const std::filesystem::path& path, std::string_view action,
                                        const std::function<void()>& task, const ChildWait& wait);

/// How long the pre-read of a file of `bytes` bytes may take before it is
/// taken for a hang (io/IsolatedIo.cpp: a generous multiple of the time a
/// valid file takes, growing with its size).
[[nodiscard]] std::chrono::milliseconds pre_read_bound(std::uintmax_t bytes);

/// Thrown by pre_read_in_child when SIGINT, SIGTERM or SIGHUP came while it
/// waited (io/Interrupt.hpp): the child was killed, the file is not known to
/// be readable, and the command should end as an interrupted one.
class PreReadInterrupted : public std::exception {
 public:
  explicit PreReadInterrupted(int signal_number) : signal(signal_number) {}
  [[nodiscard]] const char* what() const noexcept override {
    return "interrupted while a file was read in a child process";
  }
  int signal;
};

/// Runs `read` in a child process, at most `bound`, stopped by a signal.
/// Returns when the child returned or threw: the caller then reads the file
/// itself and gets the same result, or the same error.  Throws
/// std::runtime_error "cannot <action> '<path>': the NetCDF/HDF5 library
/// crashed reading it (SIGSEGV): the file is damaged" when the child crashed,
/// "... did not finish reading it in N s ..." when it ran out of time, and
/// PreReadInterrupted when a signal reached this process meanwhile.
void pre_read_in_child(const std::filesystem::path& path, std::string_view action,
                       const std::function<void()>& read, std::chrono::milliseconds bound);

/// The same, bounded by pre_read_bound(the size of `path`).
void pre_read_in_child(const std::filesystem::path& path, std::string_view action,
                       const std::function<void()>& read);

/// Runs `write` (which writes `path`) in a child process and waits until it
/// ends, signals or not.  Throws std::runtime_error with the message of what
/// `write` threw, or "cannot <action> '<path>': the NetCDF/HDF5 library
/// crashed writing it (SIGSEGV) ..." when the child crashed.  The caller owns
/// the file: it removes it after an error (PartialFile).
void write_in_child(const std::filesystem::path& path, std::string_view action,
                    const std::function<void()>& write);

}  // namespace ehlsim
