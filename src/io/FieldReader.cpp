#include "io/FieldReader.hpp"

#include <fmt/format.h>
#include <netcdf.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <span>
#include <stdexcept>
#include <string>

#include "config/Parameters.hpp"
#include "io/IsolatedIo.hpp"
#include "io/NetcdfStatus.hpp"

namespace ehlsim {

namespace {
/// Relative tolerance on the uniform spacing of the stored coordinate.
constexpr double kCoordinateTolerance = 1e-9;
/// More snapshots than a run writes (a million steps, each one stored): a
/// longer time dimension is a damaged file, not a reason to allocate its times.
constexpr std::size_t kMaxSnapshots = 1'000'000;
}  // namespace

void FieldReader::check(int status, const char* what) const {
  check_netcdf(status, "read", path_, what);
}

FieldReader::FieldReader(const std::filesystem::path& path) : path_(path) {
  require_netcdf4_file(path, "read");
  check(nc_open(netcdf_path(path).c_str(), NC_NOWRITE, &ncid_), "nc_open");
  try {
    int dim_time = -1;
    int dim_x = -1;
    int dim_y = -1;
    check(nc_inq_dimid(ncid_, "time", &dim_time), "dimension time");
    check(nc_inq_dimid(ncid_, "x", &dim_x), "dimension x");
    check(nc_inq_dimid(ncid_, "y", &dim_y), "dimension y");
    std::size_t snapshots = 0;
    std::size_t n = 0;
    std::size_t n_y = 0;
    check(nc_inq_dimlen(ncid_, dim_time, &snapshots), "dimension time");
    check(nc_inq_dimlen(ncid_, dim_x, &n), "dimension x");
    check(nc_inq_dimlen(ncid_, dim_y, &n_y), "dimension y");
    if (n < 3) throw std::runtime_error(fmt::format("'{}': fewer than 3 points", path.string()));
    if (n_y != n || n > static_cast<std::size_t>(kMaxGridPoints) || snapshots > kMaxSnapshots) {
      throw std::runtime_error(
          fmt::format("'{}': {} snapshots of {} x {} points; ehlsim writes n x n, n <= {}, and at "
                      "most {} snapshots",
                      path.string(), snapshots, n_y, n, kMaxGridPoints, kMaxSnapshots));
    }
    int var_x = -1;
    int var_time = -1;
    check(nc_inq_varid(ncid_, "x", &var_x), "variable x");
    check(nc_inq_varid(ncid_, "time", &var_time), "variable time");
    check(nc_inq_varid(ncid_, "P", &var_P_), "variable P");
    require_variable_dimensions(ncid_, var_x, {dim_x}, "read", path);
    require_variable_dimensions(ncid_, var_time, {dim_time}, "read", path);
    require_variable_dimensions(ncid_, var_P_, {dim_time, dim_y, dim_x}, "read", path);
    std::vector<double> X(n);
    check(nc_get_var_double(ncid_, var_x, X.data()), "variable x");
    const double half_width = -X.front();
    if (!(std::isfinite(half_width) && half_width > 0.0)) {
      throw std::runtime_error(fmt::format("'{}': x starts at {}, not at a finite -half_width < 0",
                                           path.string(), X.front()));
    }
    grid_ = Grid2D(static_cast<int>(n), half_width);
    for (std::size_t i = 0; i < n; ++i) {
      if (!(std::abs(X[i] - grid_.x(static_cast<int>(i))) <= kCoordinateTolerance * half_width)) {
        throw std::runtime_error(
            fmt::format("'{}': x is not the uniform symmetric grid ehlsim writes", path.string()));
      }
    }
    times_.resize(snapshots);
    if (snapshots > 0) check(nc_get_var_double(ncid_, var_time, times_.data()), "variable time");
  } catch (...) {
    nc_close(ncid_);
    ncid_ = -1;
    throw;
  }
}

FieldReader::~FieldReader() {
  if (ncid_ >= 0) nc_close(ncid_);
}

Field FieldReader::pressure(std::size_t index) const {
  if (index >= times_.size()) throw std::out_of_range("FieldReader::pressure: no such snapshot");
  Field P(grid_);
  const auto n = static_cast<std::size_t>(grid_.n);
  const std::array<std::size_t, 3> start = {index, 0, 0};
  const std::array<std::size_t, 3> count = {1, n, n};
  check(nc_get_vara_double(ncid_, var_P_, start.data(), count.data(), P.data()), "variable P");
  // HDF5 gives the fill value for a chunk it lost (one flipped bit of a
  // fields.nc): 9.97e36 everywhere there, a pressure no run writes.
  const std::span<const double> values = P.span();
  if (const auto lost = std::find(values.begin(), values.end(), NC_FILL_DOUBLE);
      lost != values.end()) {
    const auto at = static_cast<int>(lost - values.begin());
    throw std::runtime_error(fmt::format(
        "cannot read '{}': variable P of snapshot {} has no data at point ({}, {}) (the NetCDF "
        "fill value {:g}: a part of the file is lost)",
        path_.string(), index, at % grid_.n, at / grid_.n, NC_FILL_DOUBLE));
  }
  return P;
}

void pre_read_fields_in_child(const std::filesystem::path& path) {
  pre_read_in_child(path, "read", [&path] {
    const FieldReader reader(path);
    for (std::size_t k = 0; k < reader.times().size(); ++k) (void)reader.pressure(k);
  });
}

}  // namespace ehlsim
