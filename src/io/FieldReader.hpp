#pragma once
// Reads the fields.nc of an impact run as FieldWriter writes it: the grid (from
// the coordinate x), the snapshot times (the coordinate time) and the pressure P
// of each snapshot.  Files written before the coordinates were named like their
// dimensions (X, Y, T) are not read: "variable x" is missing.
#include <cstddef>
#include <filesystem>
#include <vector>

#include "grid/Grid.hpp"

namespace ehlsim {

class FieldReader {
 public:
  /// Opens the file and reads x and time.  Throws std::runtime_error naming
  /// the file and the NetCDF message, or what is missing or inconsistent.
  explicit FieldReader(const std::filesystem::path& path);
  ~FieldReader();
  FieldReader(const FieldReader&) = delete;
  FieldReader& operator=(const FieldReader&) = delete;

  [[nodiscard]] const Grid2D& grid() const { return grid_; }
  [[nodiscard]] const std::vector<double>& times() const { return times_; }
  /// P of snapshot `index` (0 <= index < times().size()).
  [[nodiscard]] Field pressure(std::size_t index) const;

 private:
  void check(int status, const char* what) const;

  std::filesystem::path path_;
  int ncid_ = -1;
  int var_P_ = -1;
  Grid2D grid_;
  std::vector<double> times_;
};

/// Reads the whole of `path` as an analysis does (FieldReader, then the P of
/// every snapshot) in a child process (io/IsolatedIo.hpp): call it before a
/// FieldReader of a file from outside this process, so that a file HDF5
/// crashes or hangs on gives a std::runtime_error naming it.  Returns when the
/// child read it, or failed with an error the FieldReader will give again.
/// Throws PreReadInterrupted after a signal meanwhile.
void pre_read_fields_in_child(const std::filesystem::path& path);

}  // namespace ehlsim
