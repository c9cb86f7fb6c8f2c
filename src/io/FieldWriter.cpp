#include "io/FieldWriter.hpp"

#include <fmt/format.h>
#include <netcdf.h>

#include <array>
#include <cerrno>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "io/NetcdfStatus.hpp"

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

void FieldWriter::check(int status, const char* what) const {
  // errno, cleared before the writing calls, has the reason of a failed write.
  check_netcdf_write(status, "write", file_.part_path(), what);
}

FieldLayout FieldLayout::impact(const Grid2D& grid) {
  FieldLayout layout;
  for (int i = 0; i < grid.n; ++i) layout.x.push_back(grid.x(i));
  for (int j = 0; j < grid.n; ++j) layout.y.push_back(grid.y(j));
  layout.title = kImpactTitle;
  return layout;
}

void FieldWriter::put_text(int var, const char* name, const std::string& value) const {
  check(nc_put_att_text(ncid_, var, name, value.size(), value.c_str()), name);
}

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
  errno = 0;
  check(nc_create(file_.part_path().c_str(), NC_NETCDF4 | NC_CLOBBER, &ncid_), "nc_create");
  try {
    define_coordinates();
    define_fields();
    put_global_attributes(parameters);
    check(nc_enddef(ncid_), "nc_enddef");
    write_coordinates();
  } catch (...) {
    nc_close(ncid_);
    ncid_ = -1;
    throw;
  }
}

// CF coordinate variables carry the name of their dimension.  x and y have no
// `axis` attribute on purpose: ParaView's NetCDF (CF) reader takes axis X and
// Y for longitude and latitude and, by default, maps the grid onto a sphere.
// Without it, it reads a uniform grid on the true X, Y.  time's `axis` T is
// what makes that reader see the snapshots as time steps (without it: none);
// its unit is "1" because T = t / t_bar is dimensionless ("seconds since ..."
// would be untrue, and xarray would decode it as dates).
void FieldWriter::define_coordinates() {
  check(nc_def_dim(ncid_, "time", NC_UNLIMITED, &dim_time_), "nc_def_dim(time)");
  check(nc_def_dim(ncid_, "y", layout_.y.size(), &dim_y_), "nc_def_dim(y)");
  check(nc_def_dim(ncid_, "x", layout_.x.size(), &dim_x_), "nc_def_dim(x)");
  const auto coordinate = [&](const char* name, int dim, const char* long_name, int* var) {
    check(nc_def_var(ncid_, name, NC_DOUBLE, 1, &dim, var), name);
    put_text(*var, "long_name", long_name);
    put_text(*var, "units", kDimensionless);
  };
  coordinate("time", dim_time_, "dimensionless time T = t / t_bar", &var_time_);
  put_text(var_time_, "axis", "T");
  coordinate("y", dim_y_, "dimensionless coordinate Y = y / a*", &var_y_);
  coordinate("x", dim_x_, "dimensionless coordinate X = x / a*", &var_x_);
}

void FieldWriter::define_fields() {
  const std::array<int, 3> dims = {dim_time_, dim_y_, dim_x_};
  const std::array<std::size_t, 3> chunk = {1, layout_.y.size(), layout_.x.size()};
  const auto field = [&](const char* name, const char* long_name, int* var) {
    check(nc_def_var(ncid_, name, NC_DOUBLE, 3, dims.data(), var), "nc_def_var");
    check(nc_def_var_chunking(ncid_, *var, NC_CHUNKED, chunk.data()), "nc_def_var_chunking");
    check(nc_def_var_deflate(ncid_, *var, kShuffle, kDeflate, kDeflateLevel), "nc_def_var_deflate");
    put_text(*var, "long_name", long_name);
    put_text(*var, "units", kDimensionless);
    put_text(*var, "coordinates", "time y x");
  };
  field("P", "dimensionless pressure P = p / ph*", &var_P_);
  field("H", "dimensionless film thickness H = h R / a*^2", &var_H_);
}

void FieldWriter::put_global_attributes(const nlohmann::json& parameters) {
  put_text(NC_GLOBAL, "Conventions", kConventions);
  put_text(NC_GLOBAL, "title", layout_.title);
  put_text(NC_GLOBAL, "source", std::string("ehlsim ") + EHLSIM_VERSION);
  put_text(NC_GLOBAL, "references", kReferences);
  put_text(NC_GLOBAL, "ehlsim_version", EHLSIM_VERSION);
  put_text(NC_GLOBAL, "ehlsim_parameters", parameters.dump());
  const nlohmann::json flat = flatten_parameters(parameters);
  for (auto it = flat.begin(); it != flat.end(); ++it) {
    const std::string& name = it.key();
    const nlohmann::json& v = *it;
    if (v.is_boolean()) {
      put_text(NC_GLOBAL, name.c_str(), v.get<bool>() ? "true" : "false");
    } else if (v.is_number_integer()) {
      const int i = v.get<int>();
      check(nc_put_att_int(ncid_, NC_GLOBAL, name.c_str(), NC_INT, 1, &i), name.c_str());
    } else if (v.is_number()) {
      const double d = v.get<double>();
      check(nc_put_att_double(ncid_, NC_GLOBAL, name.c_str(), NC_DOUBLE, 1, &d), name.c_str());
    } else if (v.is_string()) {
      put_text(NC_GLOBAL, name.c_str(), v.get<std::string>());
    } else if (v.is_array()) {
      if (v.empty()) continue;  // e.g. no output.snapshot_times: nothing to record
      const std::vector<double> values = v.get<std::vector<double>>();
      check(nc_put_att_double(ncid_, NC_GLOBAL, name.c_str(), NC_DOUBLE, values.size(),
                              values.data()),
            name.c_str());
    } else {
      put_text(NC_GLOBAL, name.c_str(), "none");  // null: e.g. time.T_end until lift-off
    }
  }
}

void FieldWriter::write_coordinates() {
  check(nc_put_var_double(ncid_, var_x_, layout_.x.data()), "nc_put_var(x)");
  check(nc_put_var_double(ncid_, var_y_, layout_.y.data()), "nc_put_var(y)");
}

FieldWriter::~FieldWriter() {
  if (ncid_ >= 0) nc_close(ncid_);  // then file_ removes the partial file
}

void FieldWriter::append(double T, std::span<const double> P, std::span<const double> H) {
  if (ncid_ < 0) throw std::logic_error("FieldWriter::append after commit");
  if (P.size() != layout_.points() || H.size() != layout_.points()) {
    throw std::invalid_argument(
        fmt::format("FieldWriter: fields of {} and {} points on a grid of {} x {}", P.size(),
                    H.size(), layout_.x.size(), layout_.y.size()));
  }
  const std::size_t index = snapshots_;
  errno = 0;
  check(nc_put_var1_double(ncid_, var_time_, &index, &T), "nc_put_var1(time)");
  const std::array<std::size_t, 3> start = {index, 0, 0};
  const std::array<std::size_t, 3> count = {1, layout_.y.size(), layout_.x.size()};
  check(nc_put_vara_double(ncid_, var_P_, start.data(), count.data(), P.data()), "nc_put_vara(P)");
  check(nc_put_vara_double(ncid_, var_H_, start.data(), count.data(), H.data()), "nc_put_vara(H)");
  ++snapshots_;
}

void FieldWriter::commit() {
  if (ncid_ < 0) return;
  errno = 0;
  const int status = nc_close(ncid_);
  ncid_ = -1;
  check(status, "nc_close");
  file_.commit();
}

}  // namespace ehlsim
