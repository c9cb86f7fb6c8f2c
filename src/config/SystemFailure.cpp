#include "config/SystemFailure.hpp"

#include <fmt/format.h>

#include <cerrno>
#include <string>
#include <system_error>

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

void throw_unreadable_input(const std::filesystem::path& path, int error) {
  const std::string message =
      fmt::format("cannot read '{}': {}", path.string(), std::generic_category().message(error));
  if (is_system_failure(error)) throw SystemFailure(message);
  throw ConfigError(message);
}

}  // namespace ehlsim
