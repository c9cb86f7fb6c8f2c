#include "config/SystemFailure.hpp"

#include <fcntl.h>
#include <fmt/format.h>
#include <unistd.h>

#include <cerrno>
#include <string>
#include <system_error>
#include <vector>

#include "config/ParameterSet.hpp"

namespace ehlsim {

bool is_system_failure(int error) {
  switch (error) {
    case EMFILE:
    case ENFILE:
    case ENOMEM:
    case ENOBUFS:
    case EAGAIN:
    case EIO:
      return true;
    default:
      return false;
  }
}

void throw_unreadable_input(const std::filesystem::path& path, int error, std::string_view action) {
  const std::string message = fmt::format("cannot {} '{}': {}", action, path.string(),
                                          std::generic_category().message(error));
  if (is_system_failure(error)) throw SystemFailure(message);
  throw ConfigError(message);
}

void throw_if_machine_cannot_read(const std::filesystem::path& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) return;  // a FIFO would wait for a writer
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) {
    if (is_system_failure(errno)) throw_unreadable_input(path, errno);
    return;
  }
  constexpr std::size_t kChunk = std::size_t{1} << 20;
  std::vector<char> buffer(kChunk);
  int error = 0;
  for (;;) {
    const ssize_t got = ::read(fd, buffer.data(), buffer.size());
    if (got > 0) continue;
    if (got < 0 && errno == EINTR) continue;
    if (got < 0) error = errno;
    break;
  }
  ::close(fd);
  if (error != 0 && is_system_failure(error)) throw_unreadable_input(path, error);
}

}  // namespace ehlsim
