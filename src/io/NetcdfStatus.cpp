#include "io/NetcdfStatus.hpp"

#include <fmt/format.h>
#include <netcdf.h>

#include <stdexcept>

namespace ehlsim {

void check_netcdf(int status, std::string_view action, const std::filesystem::path& path,
                  std::string_view what) {
  if (status != NC_NOERR) {
    throw std::runtime_error(
        fmt::format("cannot {} '{}': {}: {}", action, path.string(), what, nc_strerror(status)));
  }
}

}  // namespace ehlsim
