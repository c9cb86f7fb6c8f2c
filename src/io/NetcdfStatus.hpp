#pragma once
// The one error rule of the NetCDF files ehlsim reads and writes (fields.nc,
// checkpoint.nc), and an open file that applies it.
#include <cstddef>
#include <filesystem>
#include <initializer_list>
#include <string>
#include <string_view>

namespace ehlsim {

/// The name to give libnetcdf for `path`: a relative one behind "./", and
/// no separator repeated.  libnetcdf parses a file name as a possible URL
/// first: it dropped the leading blanks and control characters of
/// ' run/fields.nc', which did not exist, and wrote a checkpoint there; and
/// it took 'q://st/M100/fields.nc' for a URL.
[[nodiscard]] std::string netcdf_path(const std::filesystem::path& path);

/// Throws std::runtime_error "cannot <action> '<path>': <what>: <NetCDF's
/// message>" unless `status` is NC_NOERR; SystemFailure (config/SystemFailure.hpp)
/// for a system error of the machine (EMFILE, EIO, ...) that NetCDF passes on.
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

/// An open NetCDF file, closed on destruction; `action` names what is done
/// with it in error messages ("read checkpoint", "write").  A file
/// being written gives the system's reason of a failed write (errno, cleared
/// before each call: check_netcdf_write).
class NcFile {
 public:
  enum class Mode { Read, Write };
  NcFile(std::filesystem::path path, std::string_view action, Mode mode = Mode::Read);
  ~NcFile();
  NcFile(const NcFile&) = delete;
  NcFile& operator=(const NcFile&) = delete;
  /// check_netcdf, or check_netcdf_write for a file being written.
  void check(int status, std::string_view what) const;
  /// Closes the file; throws as check does when nc_close fails.
  void close();
  int id = -1;

 private:
  std::filesystem::path path_;
  std::string_view action_;
  Mode mode_;
};

}  // namespace ehlsim
