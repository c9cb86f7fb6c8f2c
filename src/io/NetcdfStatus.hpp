#pragma once
// The one error rule of the NetCDF files ehlsim reads and writes (fields.nc,
// checkpoint.nc).
#include <cstddef>
#include <filesystem>
#include <initializer_list>
#include <string_view>

namespace ehlsim {

/// Throws std::runtime_error "cannot <action> '<path>': <what>: <NetCDF's
/// message>" unless `status` is NC_NOERR.
void check_netcdf(int status, std::string_view action, const std::filesystem::path& path,
                  std::string_view what);

/// check_netcdf for a call that writes, made with errno 0 (the caller clears
/// it before the first call; each check clears it again for the next).  A
/// write that fails inside HDF5 (a full disk, an I/O error) reaches NetCDF as
/// "HDF error", and a failed nc_create as EACCES whatever its cause; errno
/// still holds the system's reason, which the message then gives:
/// "cannot <action> '<path>': nc_close (Input/output error): NetCDF: HDF
/// error", or in place of a system error that is not the cause,
/// "cannot <action> '<path>': nc_create: Input/output error".
void check_netcdf_write(int status, std::string_view action, const std::filesystem::path& path,
                        std::string_view what);

/// Throws std::runtime_error "cannot <action> '<path>': not a NetCDF-4 file
/// ..." unless the file starts with the HDF5 signature.  ehlsim writes only
/// NetCDF-4, and checking before nc_open keeps other bytes away from the
/// classic-format parser of libnetcdf, which trusts the sizes in a header (a
/// 66-byte file made it ask for 2.7 GB: docs/validation.md, "Fuzzing").  A file
/// that cannot be opened is left to nc_open and its message.
void require_netcdf4_file(const std::filesystem::path& path, std::string_view action);

/// Throws std::runtime_error "cannot <action> '<path>': variable <name> must
/// have the dimensions (...)" unless variable `var` has exactly the dimensions
/// `dims`, in that order.  nc_get_var and nc_get_vara fill as many values as
/// the variable holds: the caller's buffer is sized from these dimensions.
void require_variable_dimensions(int ncid, int var, std::initializer_list<int> dims,
                                 std::string_view action, const std::filesystem::path& path);

/// Throws std::runtime_error "cannot <action> '<path>': attribute <name> must
/// hold one value" unless the global attribute `name` exists and holds exactly
/// one value: nc_get_att writes all of them into the caller's one variable.
void require_single_value_attribute(int ncid, const char* name, std::string_view action,
                                    const std::filesystem::path& path);

}  // namespace ehlsim
