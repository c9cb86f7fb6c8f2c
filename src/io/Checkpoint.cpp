#include "io/Checkpoint.hpp"

#include <fmt/format.h>
#include <netcdf.h>

#include <array>
#include <cmath>
#include <stdexcept>
#include <string_view>
#include <utility>
#include <vector>

#include "io/AtomicFile.hpp"
#include "io/FieldWriter.hpp"
#include "io/NetcdfStatus.hpp"
#include "io/Parameters.hpp"

namespace ehlsim {

namespace {

constexpr const char* kFormatName = "ehlsim checkpoint";
/// Raised when the layout of the file changes; a reader accepts only its own.
/// 2: summary_initial_elastic_energy (the energy bounds of a run).
constexpr int kFormatVersion = 2;

/// The double-valued scalars of the state, by attribute name: one list serves
/// writing and reading, so the two cannot drift apart.
template <class State, class Visit>
void for_each_scalar(State& s, Visit&& visit) {
  visit("T", s.ball.T);
  visit("Delta", s.ball.Delta);
  visit("dDelta_dT", s.ball.V);
  visit("d2Delta_dT2", s.ball.A);
  visit("force", s.force);
  visit("force_before", s.force_before);
  visit("summary_T_final", s.summary.T_final);
  visit("summary_max_force", s.summary.max_force);
  visit("summary_T_max_force", s.summary.T_max_force);
  visit("summary_min_h_center", s.summary.min_h_center);
  visit("summary_T_min_h_center", s.summary.T_min_h_center);
  visit("summary_initial_force", s.summary.initial_force);
  visit("summary_impulse", s.summary.impulse);
  visit("summary_T_lift_off", s.summary.T_lift_off);
  visit("summary_rebound_speed", s.summary.rebound_speed);
  visit("summary_initial_elastic_energy", s.summary.initial_elastic_energy);
}

template <class State, class Visit>
void for_each_integer(State& s, Visit&& visit) {
  visit("step", s.step);
  visit("summary_steps", s.summary.steps);
  visit("summary_unconverged_steps", s.summary.unconverged_steps);
  visit("summary_retried_steps", s.summary.retried_steps);
}

template <class State, class Visit>
void for_each_field(State& s, Visit&& visit) {
  visit("P", "pressure at the last time level", s.P);
  visit("P_before", "pressure at the time level before", s.P_before);
  visit("rhoH", "rho H at the last time level", s.rhoH);
  visit("rhoH_before", "rho H at the time level before", s.rhoH_before);
}

/// An open NetCDF file, closed on destruction; `action` names what is done
/// with it in error messages ("read checkpoint", "write checkpoint").
class NcFile {
 public:
  NcFile(std::filesystem::path path, std::string_view action)
      : path_(std::move(path)), action_(action) {}
  ~NcFile() {
    if (id >= 0) nc_close(id);
  }
  NcFile(const NcFile&) = delete;
  NcFile& operator=(const NcFile&) = delete;
  void check(int status, std::string_view what) const {
    check_netcdf(status, action_, path_, what);
  }
  void close() {
    const int status = nc_close(id);
    id = -1;
    check(status, "nc_close");
  }
  int id = -1;

 private:
  std::filesystem::path path_;
  std::string_view action_;
};

/// Reads the one value of a global attribute (nc_get_att would write as many
/// values as the file holds into `value`).
template <class Value, class Get>
void read_single_value(const NcFile& nc, const std::filesystem::path& path, const char* name,
                       Value& value, Get get) {
  require_single_value_attribute(nc.id, name, "read checkpoint", path);
  nc.check(get(nc.id, NC_GLOBAL, name, &value), name);
}

std::string read_text_attribute(const NcFile& nc, const char* name) {
  std::size_t length = 0;
  nc.check(nc_inq_attlen(nc.id, NC_GLOBAL, name, &length), name);
  std::string text(length, '\0');
  nc.check(nc_get_att_text(nc.id, NC_GLOBAL, name, text.data()), name);
  return text;
}

}  // namespace

void write_checkpoint(const std::filesystem::path& path, const ImpactState& state,
                      const nlohmann::json& parameters) {
  PartialFile file(path);
  {
    NcFile nc(file.part_path(), "write checkpoint");
    nc.check(nc_create(file.part_path().c_str(), NC_NETCDF4 | NC_CLOBBER, &nc.id), "nc_create");
    const auto text = [&](const char* name, const std::string& value) {
      nc.check(nc_put_att_text(nc.id, NC_GLOBAL, name, value.size(), value.c_str()), name);
    };
    text("title", kFormatName);
    nc.check(nc_put_att_int(nc.id, NC_GLOBAL, "format_version", NC_INT, 1, &kFormatVersion),
             "format_version");
    text("ehlsim_version", EHLSIM_VERSION);
    text("ehlsim_parameters", parameters.dump());
    for_each_scalar(state, [&](const char* name, double value) {
      nc.check(nc_put_att_double(nc.id, NC_GLOBAL, name, NC_DOUBLE, 1, &value), name);
    });
    for_each_integer(state, [&](const char* name, int value) {
      nc.check(nc_put_att_int(nc.id, NC_GLOBAL, name, NC_INT, 1, &value), name);
    });
    const int had_pressure = state.had_pressure ? 1 : 0;
    nc.check(nc_put_att_int(nc.id, NC_GLOBAL, "had_pressure", NC_INT, 1, &had_pressure),
             "had_pressure");

    const auto n = static_cast<std::size_t>(state.P.n());
    std::array<int, 2> dims{};
    nc.check(nc_def_dim(nc.id, "y", n, &dims[0]), "nc_def_dim(y)");
    nc.check(nc_def_dim(nc.id, "x", n, &dims[1]), "nc_def_dim(x)");
    std::vector<std::pair<int, const Field*>> variables;
    for_each_field(state, [&](const char* name, const char* long_name, const Field& f) {
      if (static_cast<std::size_t>(f.n()) != n)
        throw std::invalid_argument("write_checkpoint: the fields differ in size");
      int var = -1;
      nc.check(nc_def_var(nc.id, name, NC_DOUBLE, 2, dims.data(), &var), name);
      nc.check(
          nc_put_att_text(nc.id, var, "long_name", std::string_view(long_name).size(), long_name),
          name);
      variables.emplace_back(var, &f);
    });
    nc.check(nc_enddef(nc.id), "nc_enddef");
    for (const auto& [var, f] : variables)
      nc.check(nc_put_var_double(nc.id, var, f->data()), "nc_put_var");
    nc.close();
  }
  file.commit();
}

Checkpoint read_checkpoint(const std::filesystem::path& path) {
  require_netcdf4_file(path, "read checkpoint");
  NcFile nc(path, "read checkpoint");
  nc.check(nc_open(path.c_str(), NC_NOWRITE, &nc.id), "nc_open");
  int version = 0;
  std::size_t version_values = 0;
  if (nc_inq_attlen(nc.id, NC_GLOBAL, "format_version", &version_values) != NC_NOERR ||
      version_values != 1 ||
      nc_get_att_int(nc.id, NC_GLOBAL, "format_version", &version) != NC_NOERR ||
      read_text_attribute(nc, "title") != kFormatName) {
    throw std::runtime_error(fmt::format("'{}' is not an ehlsim checkpoint (no \"{}\" title)",
                                         path.string(), kFormatName));
  }
  if (version != kFormatVersion) {
    throw std::runtime_error(
        fmt::format("checkpoint '{}' has format version {}; this ehlsim reads {}", path.string(),
                    version, kFormatVersion));
  }
  Checkpoint c;
  try {
    c.parameters = nlohmann::json::parse(read_text_attribute(nc, "ehlsim_parameters"));
  } catch (const nlohmann::json::exception& e) {
    throw std::runtime_error(fmt::format("checkpoint '{}': its parameters are not valid JSON: {}",
                                         path.string(), e.what()));
  }
  ImpactState& s = c.state;
  for_each_scalar(s, [&](const char* name, double& value) {
    read_single_value(nc, path, name, value, nc_get_att_double);
  });
  for_each_integer(s, [&](const char* name, int& value) {
    read_single_value(nc, path, name, value, nc_get_att_int);
  });
  int had_pressure = 0;
  read_single_value(nc, path, "had_pressure", had_pressure, nc_get_att_int);
  s.had_pressure = had_pressure != 0;

  int dim_x = -1;
  int dim_y = -1;
  std::size_t n = 0;
  std::size_t n_y = 0;
  nc.check(nc_inq_dimid(nc.id, "x", &dim_x), "dimension x");
  nc.check(nc_inq_dimlen(nc.id, dim_x, &n), "dimension x");
  nc.check(nc_inq_dimid(nc.id, "y", &dim_y), "dimension y");
  nc.check(nc_inq_dimlen(nc.id, dim_y, &n_y), "dimension y");
  if (n_y != n || n < static_cast<std::size_t>(kMinGridPoints) ||
      n > static_cast<std::size_t>(kMaxGridPoints)) {
    throw std::runtime_error(fmt::format(
        "checkpoint '{}': its fields have {} x {} points; ehlsim writes n x n, n between {} and {}",
        path.string(), n_y, n, kMinGridPoints, kMaxGridPoints));
  }
  double half_width = 0.0;
  try {
    half_width = c.parameters.at("grid").at("half_width").get<double>();
  } catch (const nlohmann::json::exception&) {
    throw std::runtime_error(
        fmt::format("checkpoint '{}': its parameters have no grid.half_width", path.string()));
  }
  if (!(std::isfinite(half_width) && half_width > 0.0)) {
    throw std::runtime_error(
        fmt::format("checkpoint '{}': its grid.half_width = {} is not a positive number",
                    path.string(), half_width));
  }
  const Grid2D grid(static_cast<int>(n), half_width);
  for_each_field(s, [&](const char* name, const char*, Field& f) {
    f = Field(grid);
    int var = -1;
    nc.check(nc_inq_varid(nc.id, name, &var), name);
    require_variable_dimensions(nc.id, var, {dim_y, dim_x}, "read checkpoint", path);
    nc.check(nc_get_var_double(nc.id, var, f.data()), name);
  });
  return c;
}

void check_restart_compatible(const nlohmann::json& checkpoint_parameters,
                              const nlohmann::json& parameters, const std::string& file) {
  // Keys that do not change the discrete problem being solved.
  const auto free_to_change = [](const std::string& key) {
    if (key == "solver_face_mean") return false;
    return key.starts_with("solver_") || key.starts_with("output_") || key.starts_with("spike_") ||
           key == "time_T_end" || key == "time_max_steps";
  };
  const nlohmann::json saved = flatten_parameters(checkpoint_parameters);
  const nlohmann::json now = flatten_parameters(parameters);
  // The flattened names join section and key with '_'; the message uses the dotted key.
  const auto dotted = [](std::string key) {
    if (const auto at = key.find('_'); at != std::string::npos) key[at] = '.';
    return key;
  };
  for (const nlohmann::json* side : {&now, &saved}) {
    for (auto it = side->begin(); it != side->end(); ++it) {
      if (free_to_change(it.key())) continue;
      const auto a = now.find(it.key());
      const auto b = saved.find(it.key());
      const std::string value_now = a == now.end() ? "(not set)" : a->dump();
      const std::string value_saved = b == saved.end() ? "(not set)" : b->dump();
      if (value_now != value_saved) {
        throw ConfigError(
            fmt::format("{} = {}, but checkpoint '{}' was written with {} (a restart continues "
                        "the same case: only solver.*, output.*, spike.*, time.T_end and "
                        "time.max_steps may "
                        "change, solver.face_mean excepted)",
                        dotted(it.key()), value_now, file, value_saved),
            dotted(it.key()));
      }
    }
  }
}

}  // namespace ehlsim
