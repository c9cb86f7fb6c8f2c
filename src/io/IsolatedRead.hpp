#pragma once
// A file from outside this process (the checkpoint of `ehlsim impact
// --restart`, the fields.nc of `ehlsim spike`) is read in a child process
// first.  HDF5 1.10.8 crashes (SIGSEGV in H5HG_read) or loops for ever (in
// H5HG's heap parser) on some files damaged inside its metadata
// (docs/validation.md, "Fuzzing and sanitizers"); ehlsim cannot check that
// metadata before HDF5 reads it.  The child makes the very read the caller is
// about to make: a crash or a hang happens there, and the caller gets a
// std::runtime_error naming the file instead of dying with it.
#include <chrono>
#include <cstdint>
#include <exception>
#include <filesystem>
#include <functional>
#include <string_view>

namespace ehlsim {

/// How long the pre-read of a file of `bytes` bytes may take before it is
/// taken for a hang (io/IsolatedRead.cpp: a generous multiple of the time a
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

/// Runs `read` in a child process and waits for it, at most `bound`.  The
/// child has no output (stdout and stderr go to /dev/null) and ends with
/// _exit: 0 when `read` returned, 2 when it threw.  Returns when the child
/// ended either way: the caller then reads the file itself and gets the same
/// result, or the same error.  Throws std::runtime_error "cannot <action>
/// '<path>': the NetCDF/HDF5 library crashed reading it (SIGSEGV): the file is
/// damaged" when the child died of a signal (or ended otherwise: a sanitizer's
/// report), "... did not finish reading it in N s ..." when it ran out of time
/// (it is killed), and PreReadInterrupted when a signal reached this process
/// meanwhile.  `read` must not use OpenMP: the child has none of the parent's
/// threads.
void pre_read_in_child(const std::filesystem::path& path, std::string_view action,
                       const std::function<void()>& read, std::chrono::milliseconds bound);

/// The same, bounded by pre_read_bound(the size of `path`).
void pre_read_in_child(const std::filesystem::path& path, std::string_view action,
                       const std::function<void()>& read);

}  // namespace ehlsim
