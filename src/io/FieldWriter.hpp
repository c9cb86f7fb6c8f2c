#pragma once
// fields.nc: snapshots of the pressure P and the film thickness H (NetCDF-4,
// CF-1.8 attributes), written atomically.
//
// Layout: dimensions time (unlimited), y, x; coordinate variables X(x), Y(y),
// T(time); data P(time, y, x) and H(time, y, x) in double precision, one
// snapshot per chunk (deflate level 1 with shuffle).  Global attributes:
// Conventions, title, source, ehlsim_version, every effective parameter as
// "<section>_<name>" and the whole set as JSON text in "ehlsim_parameters".
#include <cstddef>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "grid/Grid.hpp"
#include "io/AtomicFile.hpp"

namespace ehlsim {

class FieldWriter {
 public:
  /// Creates "<path>.part" and defines the file.  `parameters` is the echo of
  /// the effective parameters (effective_parameters_json).  Throws
  /// std::runtime_error with the NetCDF message.
  FieldWriter(const std::filesystem::path& path, const Grid2D& grid,
              const nlohmann::json& parameters);
  ~FieldWriter();
  FieldWriter(const FieldWriter&) = delete;
  FieldWriter& operator=(const FieldWriter&) = delete;

  /// Appends one snapshot at time T (P and H on the grid given at construction).
  void append(double T, const Field& P, const Field& H);
  /// Closes the file and renames it to its final name.
  void commit();
  [[nodiscard]] std::size_t snapshots() const { return snapshots_; }
  [[nodiscard]] const std::filesystem::path& path() const { return file_.final_path(); }

 private:
  void check(int status, const char* what) const;

  PartialFile file_;
  Grid2D grid_;
  int ncid_ = -1;
  int var_T_ = -1;
  int var_P_ = -1;
  int var_H_ = -1;
  std::size_t snapshots_ = 0;
};

/// Flattens nested JSON objects to {"section_name": value} (for attributes).
[[nodiscard]] nlohmann::json flatten_parameters(const nlohmann::json& parameters);

}  // namespace ehlsim
