#include "io/FieldWriter.hpp"

#include <fmt/format.h>
#include <netcdf.h>

#include <array>
#include <cerrno>
#include <stdexcept>
#include <string>
#include <system_error>
#include <vector>

#include "io/NetcdfStatus.hpp"

namespace ehlsim {

namespace {

constexpr int kDeflateLevel = 1;  ///< cheap compression: P is zero outside the contact
constexpr int kShuffle = 1;
constexpr int kDeflate = 1;
constexpr const char* kConventions = "CF-1.8";
constexpr const char* kTitle =
    "ehlsim: lubricated ball impact on a flat (pressure and film thickness)";
constexpr const char* kReferences =
    "A. A. Lubrecht, C. H. Venner, Lubricants 2022, 10, 186 (model and scaling)";

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
  // A write that fails inside HDF5 (a full disk) reaches NetCDF as "HDF
  // error"; errno, cleared before the writing calls, still has the reason.
  const int error = errno;
  if (status != NC_NOERR && error != 0 && status != error) {
    check_netcdf(status, "write", file_.part_path(),
                 fmt::format("{} ({})", what, std::generic_category().message(error)));
  }
  check_netcdf(status, "write", file_.part_path(), what);
}

FieldWriter::FieldWriter(const std::filesystem::path& path, const Grid2D& grid,
                         const nlohmann::json& parameters)
    : file_(path), grid_(grid) {
  check(nc_create(file_.part_path().c_str(), NC_NETCDF4 | NC_CLOBBER, &ncid_), "nc_create");
  try {
    const auto n = static_cast<std::size_t>(grid.n);
    int dim_time = -1;
    int dim_y = -1;
    int dim_x = -1;
    check(nc_def_dim(ncid_, "time", NC_UNLIMITED, &dim_time), "nc_def_dim(time)");
    check(nc_def_dim(ncid_, "y", n, &dim_y), "nc_def_dim(y)");
    check(nc_def_dim(ncid_, "x", n, &dim_x), "nc_def_dim(x)");

    const auto text = [&](int var, const char* name, const std::string& value) {
      check(nc_put_att_text(ncid_, var, name, value.size(), value.c_str()), name);
    };
    int var_X = -1;
    int var_Y = -1;
    check(nc_def_var(ncid_, "X", NC_DOUBLE, 1, &dim_x, &var_X), "nc_def_var(X)");
    text(var_X, "long_name", "dimensionless coordinate X = x / a*");
    text(var_X, "units", "1");
    text(var_X, "axis", "X");
    check(nc_def_var(ncid_, "Y", NC_DOUBLE, 1, &dim_y, &var_Y), "nc_def_var(Y)");
    text(var_Y, "long_name", "dimensionless coordinate Y = y / a*");
    text(var_Y, "units", "1");
    text(var_Y, "axis", "Y");
    check(nc_def_var(ncid_, "T", NC_DOUBLE, 1, &dim_time, &var_T_), "nc_def_var(T)");
    text(var_T_, "long_name", "dimensionless time T = t / t_bar");
    text(var_T_, "units", "1");
    text(var_T_, "axis", "T");

    const std::array<int, 3> dims = {dim_time, dim_y, dim_x};
    const std::array<std::size_t, 3> chunk = {1, n, n};
    const auto field = [&](const char* name, const char* long_name, int* var) {
      check(nc_def_var(ncid_, name, NC_DOUBLE, 3, dims.data(), var), "nc_def_var");
      check(nc_def_var_chunking(ncid_, *var, NC_CHUNKED, chunk.data()), "nc_def_var_chunking");
      check(nc_def_var_deflate(ncid_, *var, kShuffle, kDeflate, kDeflateLevel),
            "nc_def_var_deflate");
      text(*var, "long_name", long_name);
      text(*var, "units", "1");
      text(*var, "coordinates", "T Y X");
    };
    field("P", "dimensionless pressure P = p / ph*", &var_P_);
    field("H", "dimensionless film thickness H = h R / a*^2", &var_H_);

    text(NC_GLOBAL, "Conventions", kConventions);
    text(NC_GLOBAL, "title", kTitle);
    text(NC_GLOBAL, "source", std::string("ehlsim ") + EHLSIM_VERSION);
    text(NC_GLOBAL, "references", kReferences);
    text(NC_GLOBAL, "ehlsim_version", EHLSIM_VERSION);
    text(NC_GLOBAL, "ehlsim_parameters", parameters.dump());
    const nlohmann::json flat = flatten_parameters(parameters);
    for (auto it = flat.begin(); it != flat.end(); ++it) {
      const std::string& name = it.key();
      const nlohmann::json& v = *it;
      if (v.is_boolean()) {
        text(NC_GLOBAL, name.c_str(), v.get<bool>() ? "true" : "false");
      } else if (v.is_number_integer()) {
        const int i = v.get<int>();
        check(nc_put_att_int(ncid_, NC_GLOBAL, name.c_str(), NC_INT, 1, &i), name.c_str());
      } else if (v.is_number()) {
        const double d = v.get<double>();
        check(nc_put_att_double(ncid_, NC_GLOBAL, name.c_str(), NC_DOUBLE, 1, &d), name.c_str());
      } else if (v.is_string()) {
        text(NC_GLOBAL, name.c_str(), v.get<std::string>());
      } else if (v.is_array()) {
        if (v.empty()) continue;  // e.g. no output.snapshot_times: nothing to record
        const std::vector<double> values = v.get<std::vector<double>>();
        check(nc_put_att_double(ncid_, NC_GLOBAL, name.c_str(), NC_DOUBLE, values.size(),
                                values.data()),
              name.c_str());
      } else {
        text(NC_GLOBAL, name.c_str(), "none");  // null: e.g. time.T_end until lift-off
      }
    }
    check(nc_enddef(ncid_), "nc_enddef");

    std::vector<double> coordinate(n);
    for (int i = 0; i < grid.n; ++i) coordinate[static_cast<std::size_t>(i)] = grid.x(i);
    check(nc_put_var_double(ncid_, var_X, coordinate.data()), "nc_put_var(X)");
    check(nc_put_var_double(ncid_, var_Y, coordinate.data()), "nc_put_var(Y)");
  } catch (...) {
    nc_close(ncid_);
    ncid_ = -1;
    throw;
  }
}

FieldWriter::~FieldWriter() {
  if (ncid_ >= 0) nc_close(ncid_);  // then file_ removes the partial file
}

void FieldWriter::append(double T, const Field& P, const Field& H) {
  if (ncid_ < 0) throw std::logic_error("FieldWriter::append after commit");
  if (P.n() != grid_.n || H.n() != grid_.n) {
    throw std::invalid_argument(
        fmt::format("FieldWriter: fields of {} points per side on a grid of {}", P.n(), grid_.n));
  }
  const auto n = static_cast<std::size_t>(grid_.n);
  const std::size_t index = snapshots_;
  errno = 0;
  check(nc_put_var1_double(ncid_, var_T_, &index, &T), "nc_put_var1(T)");
  const std::array<std::size_t, 3> start = {index, 0, 0};
  const std::array<std::size_t, 3> count = {1, n, n};
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
