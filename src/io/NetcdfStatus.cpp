#include "io/NetcdfStatus.hpp"

#include <fmt/format.h>
#include <netcdf.h>

#include <algorithm>
#include <array>
#include <fstream>
#include <stdexcept>

namespace ehlsim {

void check_netcdf(int status, std::string_view action, const std::filesystem::path& path,
                  std::string_view what) {
  if (status != NC_NOERR) {
    throw std::runtime_error(
        fmt::format("cannot {} '{}': {}: {}", action, path.string(), what, nc_strerror(status)));
  }
}

void require_netcdf4_file(const std::filesystem::path& path, std::string_view action) {
  // The HDF5 format signature: the first 8 bytes of every NetCDF-4 file ehlsim writes.
  constexpr std::array<char, 8> kSignature = {'\x89', 'H', 'D', 'F', '\r', '\n', '\x1a', '\n'};
  std::ifstream in(path, std::ios::binary);
  if (!in) return;
  std::array<char, kSignature.size()> head{};
  in.read(head.data(), head.size());
  if (in.gcount() == static_cast<std::streamsize>(head.size()) &&
      std::equal(head.begin(), head.end(), kSignature.begin()))
    return;
  throw std::runtime_error(fmt::format(
      "cannot {} '{}': not a NetCDF-4 file (ehlsim reads and writes NetCDF-4/HDF5 only; the "
      "file does not start with the HDF5 signature)",
      action, path.string()));
}

}  // namespace ehlsim
