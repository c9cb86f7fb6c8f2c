#include "io/NetcdfStatus.hpp"

#include <fmt/format.h>
#include <netcdf.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <string>
#include <system_error>
#include <vector>

#include "config/SystemFailure.hpp"

namespace ehlsim {

std::string netcdf_path(const std::filesystem::path& path) {
  std::string name = path.is_absolute() ? path.string() : "./" + path.string();
  // A repeated separator is one; libnetcdf took 'q://st/M100/fields.nc' for a URL.
  const auto repeated = [](char a, char b) { return a == '/' && b == '/'; };
  name.erase(std::unique(name.begin(), name.end(), repeated), name.end());
  return name;
}

void check_netcdf(int status, std::string_view action, const std::filesystem::path& path,
                  std::string_view what) {
  if (status == NC_NOERR) return;
  const std::string message =
      fmt::format("cannot {} '{}': {}: {}", action, path.string(), what, nc_strerror(status));
  // A system error number passed on by NetCDF: EMFILE is no damaged file.
  if (status > 0 && is_system_failure(status)) throw SystemFailure(message);
  throw std::runtime_error(message);
}

void check_netcdf_write(int status, std::string_view action, const std::filesystem::path& path,
                        std::string_view what) {
  const int error = errno;
  errno = 0;
  if (status == NC_NOERR || error == 0 || error == status) {
    check_netcdf(status, action, path, what);
  } else if (status > 0) {
    // A system error number passed on by NetCDF: EACCES for any failure of
    // HDF5's create (netcdf-c's nc4_create_file), which errno names.
    throw std::runtime_error(fmt::format("cannot {} '{}': {}: {}", action, path.string(), what,
                                         std::generic_category().message(error)));
  } else {
    check_netcdf(status, action, path,
                 fmt::format("{} ({})", what, std::generic_category().message(error)));
  }
}

void require_netcdf4_file(const std::filesystem::path& path, std::string_view action) {
  // The HDF5 format signature: the first 8 bytes of every NetCDF-4 file ehlsim writes.
  constexpr std::array<char, 8> kSignature = {'\x89', 'H', 'D', 'F', '\r', '\n', '\x1a', '\n'};
  // libnetcdf reads a backslash as a directory separator: "NetCDF: HDF error",
  // as if the file were damaged.
  if (path.string().find('\\') != std::string::npos) {
    throw std::runtime_error(fmt::format(
        "cannot {} '{}': the path holds a backslash, which the NetCDF library reads as a "
        "directory separator: rename it, or give it by a link whose path has none",
        action, path.string()));
  }
  // Opening a FIFO would wait for a writer, in HDF5 beyond the reach of a signal.
  std::error_code ec;
  const std::filesystem::file_status status = std::filesystem::status(path, ec);
  if (std::filesystem::exists(status) && !std::filesystem::is_regular_file(status)) {
    throw std::runtime_error(fmt::format(
        "cannot {} '{}': not a regular file (a directory, FIFO or device)", action, path.string()));
  }
  // A file that cannot be opened is left to the library, whose message names the reason.
  const std::unique_ptr<std::FILE, int (*)(std::FILE*)> file(std::fopen(path.c_str(), "rb"),
                                                             &std::fclose);
  if (!file) return;
  std::array<char, kSignature.size()> head{};
  const std::size_t got = std::fread(head.data(), 1, head.size(), file.get());
  // An I/O error is no file of another format (/proc/self/mem: EIO at its first byte).
  if (std::ferror(file.get())) throw_unreadable_input(path, errno, action);
  if (got == head.size() && std::equal(head.begin(), head.end(), kSignature.begin())) return;
  throw std::runtime_error(fmt::format(
      "cannot {} '{}': not a NetCDF-4 file (ehlsim reads and writes NetCDF-4/HDF5 only; the "
      "file does not start with the HDF5 signature)",
      action, path.string()));
}

void require_variable_dimensions(int ncid, int var, std::initializer_list<int> dims,
                                 std::string_view action, const std::filesystem::path& path) {
  std::string name(NC_MAX_NAME + 1, '\0');
  check_netcdf(nc_inq_varname(ncid, var, name.data()), action, path, "nc_inq_varname");
  name.resize(name.find('\0'));
  std::string expected;
  for (const int dim : dims) {
    std::string dim_name(NC_MAX_NAME + 1, '\0');
    check_netcdf(nc_inq_dimname(ncid, dim, dim_name.data()), action, path, name);
    expected += (expected.empty() ? "" : ", ") + dim_name.substr(0, dim_name.find('\0'));
  }
  int ndims = -1;
  check_netcdf(nc_inq_varndims(ncid, var, &ndims), action, path, name);
  bool same = ndims == static_cast<int>(dims.size());
  if (same) {
    std::vector<int> actual(dims.size());
    check_netcdf(nc_inq_vardimid(ncid, var, actual.data()), action, path, name);
    same = std::equal(actual.begin(), actual.end(), dims.begin());
  }
  if (!same) {
    throw std::runtime_error(
        fmt::format("cannot {} '{}': variable {} must have the dimensions ({})", action,
                    path.string(), name, expected));
  }
}

void require_single_value_attribute(int ncid, const char* name, std::string_view action,
                                    const std::filesystem::path& path) {
  std::size_t length = 0;
  check_netcdf(nc_inq_attlen(ncid, NC_GLOBAL, name, &length), action, path, name);
  if (length != 1) {
    throw std::runtime_error(fmt::format("cannot {} '{}': attribute {} must hold one value, not {}",
                                         action, path.string(), name, length));
  }
}

NcFile::NcFile(std::filesystem::path path, std::string_view action, Mode mode)
    : path_(std::move(path)), action_(action), mode_(mode) {
  errno = 0;
}

NcFile::~NcFile() {
  if (id >= 0) nc_close(id);
}

void NcFile::check(int status, std::string_view what) const {
  if (mode_ == Mode::Write) {
    check_netcdf_write(status, action_, path_, what);
  } else {
    check_netcdf(status, action_, path_, what);
  }
}

void NcFile::close() {
  const int status = nc_close(id);
  id = -1;
  check(status, "nc_close");
}

}  // namespace ehlsim
