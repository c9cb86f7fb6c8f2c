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
// defined in one, and the snapshots are appended by others that open the
// file, write and close it.  The snapshots are held and written together, up
// to kFieldBatchBytes at a time (a child costs a fork and an open: 16 ms for
// a 33^2 snapshot that takes 1 ms to write).  The parent holds no NetCDF
// handle.  A fields file is published only when the run has ended well, so
// writing a snapshot late loses nothing.
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
  /// The long_name attributes that differ between the modes (the impact's
  /// scales; docs/model.md, sections 2 and 11).
  std::string time_name = "dimensionless time T = t / t_bar";
  std::string x_name = "dimensionless coordinate X = x / a*";
  std::string y_name = "dimensionless coordinate Y = y / a*";
  std::string film_name = "dimensionless film thickness H = h R / a*^2";

  /// The square grid of an impact run (RunOutput passes the full grid).
  [[nodiscard]] static FieldLayout impact(const Grid2D& grid);
  [[nodiscard]] std::size_t points() const { return x.size() * y.size(); }
};

/// The most snapshot bytes (P and H) a FieldWriter holds before it writes
/// them: the 2 x 16 MiB HDF5 held in its chunk cache for P and H when it
/// wrote in ehlsim's own process (the memory model's output term).  A larger
/// snapshot is written at once.
inline constexpr std::size_t kFieldBatchBytes = std::size_t{32} * 1024 * 1024;

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
  /// layout, row-major (value (i, j) at j * x.size() + i, i along X).  It is
  /// copied and written with the next ones (kFieldBatchBytes) or by commit().
  void append(double T, std::span<const double> P, std::span<const double> H);
  void append(double T, const Field& P, const Field& H) { append(T, P.span(), H.span()); }
  /// Writes the held snapshots, syncs the file to disk and renames it to its
  /// final name.
  void commit();
  [[nodiscard]] std::size_t snapshots() const { return snapshots_; }
  [[nodiscard]] const std::filesystem::path& path() const { return file_.final_path(); }

 private:
  /// A snapshot held until it is written.
  struct HeldSnapshot {
    double T;
    std::vector<double> P, H;
  };
  /// Writes the held snapshots in one child process.
  void write_held();

  PartialFile file_;
  FieldLayout layout_;
  std::vector<HeldSnapshot> held_;
  std::size_t snapshots_ = 0;  ///< appended, held or written
};

/// Flattens nested JSON objects to {"section_name": value} (for attributes).
[[nodiscard]] nlohmann::json flatten_parameters(const nlohmann::json& parameters);

}  // namespace ehlsim
