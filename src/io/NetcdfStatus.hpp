#pragma once
// The one error rule of the NetCDF files ehlsim reads and writes (fields.nc,
// checkpoint.nc).
#include <filesystem>
#include <string_view>

namespace ehlsim {

/// Throws std::runtime_error "cannot <action> '<path>': <what>: <NetCDF's
/// message>" unless `status` is NC_NOERR.
void check_netcdf(int status, std::string_view action, const std::filesystem::path& path,
                  std::string_view what);

}  // namespace ehlsim
