#pragma once
// fields.nc: snapshots of the pressure P and the film thickness H (NetCDF-4,
// CF-1.8), written atomically.
//
// Layout: dimensions time (unlimited), y, x with their coordinate variables
// time(time), y(y), x(x) (named like their dimensions, so that CF readers such
// as ParaView's NetCDF reader and xarray take them as coordinates); data
// P(time, y, x) and H(time, y, x) in double precision, one snapshot per chunk
// (deflate level 1 with shuffle).  Global attributes: Conventions, title,
// source, ehlsim_version, every effective parameter as "<section>_<name>" and
// the whole set as JSON text in "ehlsim_parameters".
//
// Every NetCDF call runs in a child process (io/IsolatedIo.hpp: HDF5 1.10.8
// crashes when the last write of a file fails): the file is created and
// defined in one, and each snapshot is appended in another that opens the
// file, writes and closes it.  The parent holds no NetCDF handle.
#include <cstddef>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <span>
#include <string>
#include <vector>

#include "grid/Grid.hpp"
#include "io/AtomicFile.hpp"

namespace ehlsim {

/// What a fields file describes: the coordinate of every column (X) and row
/// (Y) of the stored fields, which need not be square or centred (a rolling
/// contact's domain is X in [-4.5, 1.5], Y in [-3, 3]), and the file's title.
struct FieldLayout {
  std::vector<double> x;
  std::vector<double> y;
  std::string title;

  /// The square grid of an impact run (RunOutput passes the full grid).
  [[nodiscard]] static FieldLayout impact(const Grid2D& grid);
  [[nodiscard]] std::size_t points() const { return x.size() * y.size(); }
};

class FieldWriter {
 public:
  /// Creates "<path>.part" and defines the file.  `parameters` is the echo of
  /// the effective parameters (effective_parameters_json).  Throws
  /// std::runtime_error with the NetCDF message (or the child's crash).
  FieldWriter(const std::filesystem::path& path, FieldLayout layout,
              const nlohmann::json& parameters);
  /// The impact's file on `grid` (FieldLayout::impact).
  FieldWriter(const std::filesystem::path& path, const Grid2D& grid,
              const nlohmann::json& parameters);
  ~FieldWriter();
  FieldWriter(const FieldWriter&) = delete;
  FieldWriter& operator=(const FieldWriter&) = delete;

  /// Appends one snapshot at time T: P and H hold one value per point of the
  /// layout, row-major (value (i, j) at j * x.size() + i, i along X).
  void append(double T, std::span<const double> P, std::span<const double> H);
  void append(double T, const Field& P, const Field& H) { append(T, P.span(), H.span()); }
  /// Syncs the file to disk and renames it to its final name.
  void commit();
  [[nodiscard]] std::size_t snapshots() const { return snapshots_; }
  [[nodiscard]] const std::filesystem::path& path() const { return file_.final_path(); }

 private:
  PartialFile file_;
  FieldLayout layout_;
  std::size_t snapshots_ = 0;
};

/// Flattens nested JSON objects to {"section_name": value} (for attributes).
[[nodiscard]] nlohmann::json flatten_parameters(const nlohmann::json& parameters);

}  // namespace ehlsim
