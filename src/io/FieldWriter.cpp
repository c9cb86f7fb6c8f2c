#include "io/FieldWriter.hpp"

#include <fmt/format.h>
#include <netcdf.h>

#include <array>
#include <cerrno>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "io/IsolatedIo.hpp"
#include "io/NetcdfStatus.hpp"
#include "io/ProgramInfo.hpp"

namespace ehlsim {

namespace {

constexpr int kDeflateLevel = 1;  ///< cheap compression: P is zero outside the contact
constexpr int kShuffle = 1;
constexpr int kDeflate = 1;
constexpr const char* kConventions = "CF-1.8";
constexpr const char* kImpactTitle =
    "ehlsim: lubricated ball impact on a flat (pressure and film thickness)";
constexpr const char* kReferences =
    "A. A. Lubrecht, C. H. Venner, Lubricants 2022, 10, 186 (model and scaling)";
constexpr std::size_t kMinPointsPerAxis = 2;
/// The unit of every stored quantity: all are dimensionless (docs/model.md).
constexpr const char* kDimensionless = "1";

void flatten_into(const nlohmann::json& j, const std::string& prefix, nlohmann::json& out) {
  for (auto it = j.begin(); it != j.end(); ++it) {
    const std::string name = prefix.empty() ? it.key() : prefix + "_" + it.key();
    if (it->is_object()) {
      flatten_into(*it, name, out);
    } else {
      out[name] = *it;
    }
  }
}

}  // namespace

nlohmann::json flatten_parameters(const nlohmann::json& parameters) {
  nlohmann::json out = nlohmann::json::object();
  flatten_into(parameters, "", out);
  return out;
}

FieldLayout FieldLayout::impact(const Grid2D& grid) {
  FieldLayout layout;
  for (int i = 0; i < grid.n; ++i) layout.x.push_back(grid.x(i));
  for (int j = 0; j < grid.n; ++j) layout.y.push_back(grid.y(j));
  layout.title = kImpactTitle;
  return layout;
}

namespace {

/// The action of every message: "cannot write '<path>': ...".
constexpr const char* kAction = "write";

void put_text(const NcFile& nc, int var, const char* name, const std::string& value) {
  nc.check(nc_put_att_text(nc.id, var, name, value.size(), value.c_str()), name);
}

/// The dimensions of a fields file.
struct FieldDimensions {
  int time = -1;
  int y = -1;
  int x = -1;
};

// CF coordinate variables carry the name of their dimension.  x and y have no
// `axis` attribute on purpose: ParaView's NetCDF (CF) reader takes axis X and
// Y for longitude and latitude and, by default, maps the grid onto a sphere.
// Without it, it reads a uniform grid on the true X, Y.  time's `axis` T is
// what makes that reader see the snapshots as time steps (without it: none);
// its unit is "1" because T = t / t_bar is dimensionless ("seconds since ..."
// would be untrue, and xarray would decode it as dates).
FieldDimensions define_coordinates(const NcFile& nc, const FieldLayout& layout) {
  FieldDimensions dims;
  nc.check(nc_def_dim(nc.id, "time", NC_UNLIMITED, &dims.time), "nc_def_dim(time)");
  nc.check(nc_def_dim(nc.id, "y", layout.y.size(), &dims.y), "nc_def_dim(y)");
  nc.check(nc_def_dim(nc.id, "x", layout.x.size(), &dims.x), "nc_def_dim(x)");
  const auto coordinate = [&](const char* name, int dim, const std::string& long_name) {
    int var = -1;
    nc.check(nc_def_var(nc.id, name, NC_DOUBLE, 1, &dim, &var), name);
    put_text(nc, var, "long_name", long_name);
    put_text(nc, var, "units", kDimensionless);
    return var;
  };
  const int time = coordinate("time", dims.time, layout.time_name);
  put_text(nc, time, "axis", "T");
  coordinate("y", dims.y, layout.y_name);
  coordinate("x", dims.x, layout.x_name);
  return dims;
}

void define_fields(const NcFile& nc, const FieldLayout& layout, const FieldDimensions& d) {
  const std::array<int, 3> dims = {d.time, d.y, d.x};
  const std::array<std::size_t, 3> chunk = {1, layout.y.size(), layout.x.size()};
  const auto field = [&](const char* name, const std::string& long_name) {
    int var = -1;
    nc.check(nc_def_var(nc.id, name, NC_DOUBLE, 3, dims.data(), &var), "nc_def_var");
    nc.check(nc_def_var_chunking(nc.id, var, NC_CHUNKED, chunk.data()), "nc_def_var_chunking");
    nc.check(nc_def_var_deflate(nc.id, var, kShuffle, kDeflate, kDeflateLevel),
             "nc_def_var_deflate");
    put_text(nc, var, "long_name", long_name);
    put_text(nc, var, "units", kDimensionless);
    put_text(nc, var, "coordinates", "time y x");
  };
  field("P", "dimensionless pressure P = p / ph*");
  field("H", layout.film_name);
}

void put_global_attributes(const NcFile& nc, const FieldLayout& layout,
                           const nlohmann::json& parameters) {
  put_text(nc, NC_GLOBAL, "Conventions", kConventions);
  put_text(nc, NC_GLOBAL, "title", layout.title);
  put_text(nc, NC_GLOBAL, "source", program_text());
  put_text(nc, NC_GLOBAL, "references", kReferences);
  put_text(nc, NC_GLOBAL, "ehlsim_version", EHLSIM_VERSION);
  put_text(nc, NC_GLOBAL, "ehlsim_revision", std::string(source_revision()));
  put_text(nc, NC_GLOBAL, "ehlsim_parameters", parameters.dump());
  const nlohmann::json flat = flatten_parameters(parameters);
  for (auto it = flat.begin(); it != flat.end(); ++it) {
    const char* name = it.key().c_str();
    const nlohmann::json& v = *it;
    if (v.is_boolean()) {
      put_text(nc, NC_GLOBAL, name, v.get<bool>() ? "true" : "false");
    } else if (v.is_number_integer()) {
      const int i = v.get<int>();
      nc.check(nc_put_att_int(nc.id, NC_GLOBAL, name, NC_INT, 1, &i), name);
    } else if (v.is_number()) {
      const double d = v.get<double>();
      nc.check(nc_put_att_double(nc.id, NC_GLOBAL, name, NC_DOUBLE, 1, &d), name);
    } else if (v.is_string()) {
      put_text(nc, NC_GLOBAL, name, v.get<std::string>());
    } else if (v.is_array()) {
      if (v.empty()) continue;  // e.g. no output.snapshot_times: nothing to record
      const std::vector<double> values = v.get<std::vector<double>>();
      nc.check(nc_put_att_double(nc.id, NC_GLOBAL, name, NC_DOUBLE, values.size(), values.data()),
               name);
    } else {
      put_text(nc, NC_GLOBAL, name, "none");  // null: e.g. time.T_end until lift-off
    }
  }
}

/// Creates the file at `path` with its definitions and coordinates, and
/// closes it (in a child process: FieldWriter's constructor).
void create_field_file(const std::filesystem::path& path, const FieldLayout& layout,
                       const nlohmann::json& parameters) {
  NcFile nc(path, kAction, NcFile::Mode::Write);
  nc.check(nc_create(netcdf_path(path).c_str(), NC_NETCDF4 | NC_CLOBBER, &nc.id), "nc_create");
  const FieldDimensions dims = define_coordinates(nc, layout);
  define_fields(nc, layout, dims);
  put_global_attributes(nc, layout, parameters);
  nc.check(nc_enddef(nc.id), "nc_enddef");
  const auto put = [&](const char* name, const std::vector<double>& values) {
    int var = -1;
    nc.check(nc_inq_varid(nc.id, name, &var), name);
    nc.check(nc_put_var_double(nc.id, var, values.data()), "nc_put_var");
  };
  put("x", layout.x);
  put("y", layout.y);
  nc.close();
}

/// One snapshot to write: its time and its fields.
struct SnapshotView {
  double T;
  std::span<const double> P, H;
};

/// Opens the file at `path`, writes `snapshots` as snapshots `first`,
/// `first` + 1, ... and closes it (in a child process: FieldWriter).
void append_snapshots(const std::filesystem::path& path, const FieldLayout& layout,
                      std::size_t first, const std::vector<SnapshotView>& snapshots) {
  NcFile nc(path, kAction, NcFile::Mode::Write);
  nc.check(nc_open(netcdf_path(path).c_str(), NC_WRITE, &nc.id), "nc_open");
  const auto variable = [&](const char* name) {
    int var = -1;
    nc.check(nc_inq_varid(nc.id, name, &var), name);
    return var;
  };
  const int time = variable("time");
  const int var_P = variable("P");
  const int var_H = variable("H");
  std::size_t index = first;
  for (const SnapshotView& s : snapshots) {
    nc.check(nc_put_var1_double(nc.id, time, &index, &s.T), "nc_put_var1(time)");
    const std::array<std::size_t, 3> start = {index, 0, 0};
    const std::array<std::size_t, 3> count = {1, layout.y.size(), layout.x.size()};
    nc.check(nc_put_vara_double(nc.id, var_P, start.data(), count.data(), s.P.data()),
             "nc_put_vara(P)");
    nc.check(nc_put_vara_double(nc.id, var_H, start.data(), count.data(), s.H.data()),
             "nc_put_vara(H)");
    ++index;
  }
  nc.close();
}

}  // namespace

FieldWriter::FieldWriter(const std::filesystem::path& path, const Grid2D& grid,
                         const nlohmann::json& parameters)
    : FieldWriter(path, FieldLayout::impact(grid), parameters) {}

FieldWriter::FieldWriter(const std::filesystem::path& path, FieldLayout layout,
                         const nlohmann::json& parameters)
    : file_(path), layout_(std::move(layout)) {
  // A zero-length NetCDF dimension would be a second unlimited one.
  if (layout_.x.size() < kMinPointsPerAxis || layout_.y.size() < kMinPointsPerAxis) {
    throw std::invalid_argument(
        fmt::format("FieldWriter: a grid of {} x {} points", layout_.x.size(), layout_.y.size()));
  }
  write_in_child(file_.part_path(), kAction,
                 [&] { create_field_file(file_.part_path(), layout_, parameters); });
}

FieldWriter::~FieldWriter() = default;  // file_ removes the partial file unless committed

void FieldWriter::append(double T, std::span<const double> P, std::span<const double> H) {
  if (file_.committed()) throw std::logic_error("FieldWriter::append after commit");
  if (P.size() != layout_.points() || H.size() != layout_.points()) {
    throw std::invalid_argument(
        fmt::format("FieldWriter: fields of {} and {} points on a grid of {} x {}", P.size(),
                    H.size(), layout_.x.size(), layout_.y.size()));
  }
  const std::size_t bytes = 2 * layout_.points() * sizeof(double);
  if ((held_.size() + 1) * bytes > kFieldBatchBytes) write_held();
  if (bytes > kFieldBatchBytes) {
    const std::vector<SnapshotView> one = {{T, P, H}};
    write_in_child(file_.part_path(), kAction,
                   [&] { append_snapshots(file_.part_path(), layout_, snapshots_, one); });
  } else {
    held_.push_back({T, {P.begin(), P.end()}, {H.begin(), H.end()}});
  }
  ++snapshots_;
}

void FieldWriter::write_held() {
  if (held_.empty()) return;
  std::vector<SnapshotView> views;
  for (const HeldSnapshot& s : held_) views.push_back({s.T, s.P, s.H});
  const std::size_t first = snapshots_ - held_.size();
  write_in_child(file_.part_path(), kAction,
                 [&] { append_snapshots(file_.part_path(), layout_, first, views); });
  held_.clear();
}

void FieldWriter::commit() {
  if (file_.committed()) return;
  write_held();
  file_.commit();
}

}  // namespace ehlsim
