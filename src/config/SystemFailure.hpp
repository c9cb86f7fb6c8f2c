#pragma once
// Failures of the machine rather than of the input (docs/usage.md, "Errors"):
// a file of the user's that cannot be read because the process is out of
// file descriptors is no bad input, and ends the command with exit 1, not 2.
#include <filesystem>
#include <stdexcept>
#include <string_view>

namespace ehlsim {

/// A failure of the machine (out of file descriptors or memory, an I/O
/// error) where the input is read.  Code that turns the errors of reading
/// the user's files into bad input (ConfigError) lets this one pass.
class SystemFailure : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Whether the errno value `error` says that the machine failed (EMFILE,
/// ENFILE, ENOMEM, ENOBUFS, EAGAIN, EIO) rather than the file asked for.
[[nodiscard]] bool is_system_failure(int error);

/// Throws "cannot <action> '<path>': <strerror(error)>", a file of the
/// user's input that could not be opened or read: SystemFailure when
/// is_system_failure(error), else ConfigError (a missing permission, ...).
[[noreturn]] void throw_unreadable_input(const std::filesystem::path& path, int error,
                                         std::string_view action = "read");

/// Reads the regular file `path` to its end and throws SystemFailure "cannot
/// read '<path>': <strerror>" where the machine cannot (EIO, ...); returns
/// otherwise.  For an input a library found damaged ("NetCDF: HDF error"):
/// its bytes may be sound and the disk under them failing.
void throw_if_machine_cannot_read(const std::filesystem::path& path);

}  // namespace ehlsim
