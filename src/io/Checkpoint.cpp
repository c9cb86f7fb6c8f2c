#include "io/Checkpoint.hpp"

#include <fmt/format.h>
#include <netcdf.h>
#include <zlib.h>

#include <array>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <string_view>
#include <type_traits>
#include <utility>
#include <vector>

#include "config/Parameters.hpp"
#include "grid/FieldExtrema.hpp"
#include "io/AtomicFile.hpp"
#include "io/FieldWriter.hpp"
#include "io/IsolatedIo.hpp"
#include "io/NetcdfStatus.hpp"
#include "io/ProgramInfo.hpp"

namespace ehlsim {

namespace {

constexpr const char* kFormatName = "ehlsim checkpoint";
/// Raised when the layout of the file changes; a reader accepts only its own.
/// 2: summary_initial_elastic_energy (the energy bounds of a run).
/// 3: checksum_crc32 over every stored value; the reader checks plausibility.
/// 4: attempts_first and attempts_streak (impact/AttemptPolicy.hpp).
/// 5: attempts_failed_probes and attempts_probing (the same).
/// 6: P_before2 (the quadratic start, impact/PressurePredictor.hpp).
/// 7: P_before3 (the cubic start).
/// 8: summary_edge_impulse (the domain's warning, impact/RunGuards.hpp).
/// 9: splits_first, splits_streak, splits_failed_probes, splits_probing and
///    splits_last_needed (impact/AttemptPolicy.hpp, SplitMemory).
constexpr int kFormatVersion = 9;
constexpr const char* kChecksumAttribute = "checksum_crc32";
/// |T - step dT| allowed, relative to step dT: T is a running sum of dT, so
/// it differs from step dT by rounding only (about step x 1e-16).
constexpr double kStepTimeTolerance = 1e-6;

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
  visit("summary_edge_impulse", s.summary.edge_impulse);
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
  visit("attempts_first", s.attempts.first);
  visit("attempts_streak", s.attempts.streak);
  visit("attempts_failed_probes", s.attempts.failed_probes);
  visit("splits_first", s.splits.begin.first);
  visit("splits_streak", s.splits.begin.streak);
  visit("splits_failed_probes", s.splits.begin.failed_probes);
  visit("splits_last_needed", s.splits.last_needed);
}

/// The flags of the state, stored as integer attributes 0 or 1.
template <class State, class Visit>
void for_each_flag(State& s, Visit&& visit) {
  visit("had_pressure", s.had_pressure);
  visit("attempts_probing", s.attempts.probing);
  visit("splits_probing", s.splits.begin.probing);
}

template <class State, class Visit>
void for_each_field(State& s, Visit&& visit) {
  visit("P", "pressure at the last time level", s.P);
  visit("P_before", "pressure at the time level before", s.P_before);
  visit("P_before2", "pressure at the time level before that", s.P_before2);
  visit("P_before3", "pressure at the time level before that one", s.P_before3);
  visit("rhoH", "rho H at the last time level", s.rhoH);
  visit("rhoH_before", "rho H at the time level before", s.rhoH_before);
}

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

/// CRC-32 (zlib) of a sequence of names and values, in the order given.
class Crc32 {
 public:
  void add(std::string_view bytes) {
    value_ = crc32_z(value_, reinterpret_cast<const Bytef*>(bytes.data()), bytes.size());
  }
  template <class T>
  void add_value(const T& value) {
    add(std::string_view(reinterpret_cast<const char*>(&value), sizeof(T)));
  }
  void add_field(const Field& f) {
    add(std::string_view(reinterpret_cast<const char*>(f.data()), f.size() * sizeof(double)));
  }
  [[nodiscard]] std::uint32_t value() const { return static_cast<std::uint32_t>(value_); }

 private:
  uLong value_ = crc32_z(0L, Z_NULL, 0);
};

/// The checksum of everything a checkpoint stores: the format, the writer's
/// version, the parameters as written (JSON text), every scalar and field.
std::uint32_t checkpoint_checksum(const ImpactState& s, std::string_view parameters_text,
                                  std::string_view ehlsim_version) {
  Crc32 crc;
  crc.add(kFormatName);
  crc.add_value(kFormatVersion);
  crc.add(ehlsim_version);
  crc.add(parameters_text);
  for_each_scalar(s, [&](const char* name, double value) {
    crc.add(name);
    crc.add_value(value);
  });
  for_each_integer(s, [&](const char* name, int value) {
    crc.add(name);
    crc.add_value(value);
  });
  for_each_flag(s, [&](const char*, bool flag) { crc.add_value(flag ? 1 : 0); });
  crc.add_value(s.P.n());
  for_each_field(s, [&](const char* name, const char*, const Field& f) {
    crc.add(name);
    crc.add_field(f);
  });
  return crc.value();
}

template <class T>
constexpr nc_type netcdf_type() {
  if constexpr (std::is_same_v<T, double>) return NC_DOUBLE;
  if constexpr (std::is_same_v<T, int>) return NC_INT;
  if constexpr (std::is_same_v<T, std::uint32_t>) return NC_UINT;
}

/// Reads the attributes and variables of a checkpoint, checking their type
/// and size before any value is read: a damaged file gives an error that
/// names the file and the field, never an overflow.
struct CheckpointReader {
  const NcFile& nc;
  const std::filesystem::path& path;

  [[noreturn]] void fail(std::string_view field, std::string_view problem) const {
    throw std::runtime_error(
        fmt::format("checkpoint {}: field '{}' {}", path.string(), field, problem));
  }
  [[nodiscard]] bool has_attribute(const char* name, nc_type type) const {
    nc_type stored = NC_NAT;
    std::size_t length = 0;
    return nc_inq_att(nc.id, NC_GLOBAL, name, &stored, &length) == NC_NOERR && stored == type &&
           length >= 1;
  }
  template <class T>
  [[nodiscard]] T scalar(const char* name) const {
    nc_type type = NC_NAT;
    std::size_t length = 0;
    if (nc_inq_att(nc.id, NC_GLOBAL, name, &type, &length) != NC_NOERR) fail(name, "is missing");
    if (type != netcdf_type<T>() || length != 1) fail(name, "is not a single value of its type");
    T value{};
    nc.check(nc_get_att(nc.id, NC_GLOBAL, name, &value), name);
    return value;
  }
  /// A flag stored as 0 or 1; any other integer is refused (as true, it
  /// passed the checksum, which covers the flag, not the stored value).
  [[nodiscard]] bool flag(const char* name) const {
    const int value = scalar<int>(name);
    if (value != 0 && value != 1) fail(name, fmt::format("= {}: must be 0 or 1", value));
    return value == 1;
  }
  [[nodiscard]] std::string text(const char* name) const {
    if (!has_attribute(name, NC_CHAR)) fail(name, "is missing or not text");
    return read_text_attribute(nc, name);
  }
  /// The id of the double variable `name` on the (y, x) grid of n x n points.
  [[nodiscard]] int field_variable(const char* name, int n) const {
    int var = -1;
    if (nc_inq_varid(nc.id, name, &var) != NC_NOERR) fail(name, "is missing");
    int dims = 0;
    nc_type type = NC_NAT;
    nc.check(nc_inq_var(nc.id, var, nullptr, &type, &dims, nullptr, nullptr), name);
    if (type != NC_DOUBLE || dims != 2) fail(name, "is not a 2-D field of doubles");
    std::array<int, 2> ids{};
    std::array<std::size_t, 2> lengths{};
    nc.check(nc_inq_vardimid(nc.id, var, ids.data()), name);
    for (int d = 0; d < 2; ++d) nc.check(nc_inq_dimlen(nc.id, ids[d], &lengths[d]), name);
    const auto expected = static_cast<std::size_t>(n);
    if (lengths[0] != expected || lengths[1] != expected) {
      fail(name, fmt::format("has {} x {} values; the grid has {} x {} points", lengths[0],
                             lengths[1], n, n));
    }
    return var;
  }
};

/// The grid and time step of a checkpoint, from its parameters, checked
/// against the dimensions of the file.
struct CheckpointGrid {
  int n = 0;
  double half_width = 0.0;
  double dT = 0.0;
};

CheckpointGrid checkpoint_grid(const CheckpointReader& in, const nlohmann::json& parameters) {
  CheckpointGrid g;
  try {
    g.n = parameters.at("grid").at("points").get<int>();
    g.half_width = parameters.at("grid").at("half_width").get<double>();
    g.dT = parameters.at("time").at("dT").get<double>();
  } catch (const nlohmann::json::exception&) {
    in.fail("ehlsim_parameters", "has no valid grid.points, grid.half_width and time.dT");
  }
  if (g.n < kMinGridPoints || g.n > kMaxGridPoints || !(g.half_width > 0.0) ||
      !std::isfinite(g.half_width) || !(g.dT > 0.0) || !std::isfinite(g.dT)) {
    in.fail("ehlsim_parameters",
            fmt::format("has an impossible grid or time step (grid.points = {}, grid.half_width "
                        "= {}, time.dT = {})",
                        g.n, g.half_width, g.dT));
  }
  for (const char* dim : {"x", "y"}) {
    int id = -1;
    std::size_t length = 0;
    if (nc_inq_dimid(in.nc.id, dim, &id) != NC_NOERR) in.fail(dim, "(dimension) is missing");
    in.nc.check(nc_inq_dimlen(in.nc.id, id, &length), dim);
    if (length != static_cast<std::size_t>(g.n)) {
      in.fail(dim, fmt::format("(dimension) has {} points; its parameters say grid.points = {}",
                               length, g.n));
    }
  }
  return g;
}

/// Values a run cannot have stored.  NaN is allowed only where the summary
/// uses it for "not yet" (no lift-off so far).
bool may_be_nan(std::string_view name) {
  return name == "summary_T_lift_off" || name == "summary_rebound_speed";
}

void check_fields_plausible(const CheckpointReader& in, const ImpactState& s) {
  for_each_field(s, [&](const char* name, const char*, const Field& f) {
    const bool pressure = name[0] == 'P';
    const int n = f.n();
    // Pressures are >= 0 everywhere (cavitation), films at the interior
    // points of every kept step (the negative-film guard).
    const auto unsound = first_unsound_point(
        f, [&](int i, int j) { return pressure || (i > 0 && j > 0 && i < n - 1 && j < n - 1); });
    if (!unsound) return;
    const double v = unsound->value;
    const int i = unsound->i, j = unsound->j;
    if (!std::isfinite(v))
      in.fail(name, fmt::format("is not finite ({}) at point ({}, {})", v, i, j));
    in.fail(name, fmt::format("is negative ({:.6g}) at point ({}, {}): {}", v, i, j,
                              pressure ? "a pressure is >= 0" : "a film is >= 0"));
  });
}

/// An AttemptMemory stored as PREFIX_first, PREFIX_streak, ... whose `first`
/// is at most `most_first`.
void check_memory_plausible(const CheckpointReader& in, std::string_view prefix,
                            const AttemptMemory& m, int most_first) {
  const auto field = [&](const char* name) { return fmt::format("{}_{}", prefix, name); };
  if (m.first < 0 || m.first > most_first)
    in.fail(field("first"), fmt::format("= {}: must be in [0, {}]", m.first, most_first));
  if (m.failed_probes < 0 || m.failed_probes > kMaxProbeBackoff)
    in.fail(field("failed_probes"),
            fmt::format("= {}: must be in [0, {}]", m.failed_probes, kMaxProbeBackoff));
  if (m.probing && (m.first >= most_first || m.streak != 0))
    in.fail(field("probing"),
            fmt::format("= 1 with {} = {} and {} = {}: a probe needs them below {} and at 0",
                        field("first"), m.first, field("streak"), m.streak, most_first));
  const int most_streak = steps_before_probe(m.failed_probes) - 1;
  if (m.streak < 0 || m.streak > most_streak)
    in.fail(field("streak"), fmt::format("= {}: must be in [0, {}]", m.streak, most_streak));
}

void check_plausible(const CheckpointReader& in, const ImpactState& s, const CheckpointGrid& g) {
  for_each_scalar(s, [&](const char* name, double value) {
    if (!std::isfinite(value) && !(std::isnan(value) && may_be_nan(name)))
      in.fail(name, fmt::format("is not finite ({})", value));
  });
  // No run takes more steps than time.max_steps allows (a forged 2^31 - 1
  // overflowed the next step's number and ended with exit 0).
  if (s.step < 1 || s.step > kMaxTimeSteps)
    in.fail("step", fmt::format("= {}: must be in [1, {}]", s.step, kMaxTimeSteps));
  // The film force is the integral of a pressure >= 0.
  for (const auto& [name, force] :
       {std::pair{"force", s.force}, std::pair{"force_before", s.force_before}}) {
    if (force < 0.0) in.fail(name, fmt::format("= {:.6g}: a film force is >= 0", force));
  }
  const double expected_T = static_cast<double>(s.step) * g.dT;
  if (std::fabs(s.ball.T - expected_T) > kStepTimeTolerance * expected_T) {
    in.fail("step", fmt::format("= {} does not match T = {:.9g}: step x time.dT = {:.9g} "
                                "(time.dT = {:.9g})",
                                s.step, s.ball.T, expected_T, g.dT));
  }
  if (s.summary.steps != s.step) {
    in.fail("summary_steps", fmt::format("= {} differs from step = {}", s.summary.steps, s.step));
  }
  for (const auto& [name, count] :
       {std::pair{"summary_unconverged_steps", s.summary.unconverged_steps},
        std::pair{"summary_retried_steps", s.summary.retried_steps}}) {
    if (count < 0 || count > s.step)
      in.fail(name, fmt::format("= {}: must be in [0, step = {}]", count, s.step));
  }
  check_memory_plausible(in, "attempts", s.attempts, kMaxRetries);
  check_memory_plausible(in, "splits", s.splits.begin, kMaxSplitDepth);
  if (s.splits.last_needed < 0 || s.splits.last_needed > kMaxSplitDepth)
    in.fail("splits_last_needed",
            fmt::format("= {}: must be in [0, {}]", s.splits.last_needed, kMaxSplitDepth));
  check_fields_plausible(in, s);
}

/// The NetCDF file of a checkpoint at `path` (write_checkpoint's child process).
void write_checkpoint_file(const std::filesystem::path& path, const ImpactState& state,
                           const nlohmann::json& parameters) {
  NcFile nc(path, "write checkpoint", NcFile::Mode::Write);
  nc.check(nc_create(netcdf_path(path).c_str(), NC_NETCDF4 | NC_CLOBBER, &nc.id), "nc_create");
  const auto text = [&](const char* name, const std::string& value) {
    nc.check(nc_put_att_text(nc.id, NC_GLOBAL, name, value.size(), value.c_str()), name);
  };
  text("title", kFormatName);
  nc.check(nc_put_att_int(nc.id, NC_GLOBAL, "format_version", NC_INT, 1, &kFormatVersion),
           "format_version");
  text("ehlsim_version", EHLSIM_VERSION);
  text("ehlsim_revision", std::string(source_revision()));
  const std::string parameters_text = parameters.dump();
  text("ehlsim_parameters", parameters_text);
  for_each_scalar(state, [&](const char* name, double value) {
    nc.check(nc_put_att_double(nc.id, NC_GLOBAL, name, NC_DOUBLE, 1, &value), name);
  });
  for_each_integer(state, [&](const char* name, int value) {
    nc.check(nc_put_att_int(nc.id, NC_GLOBAL, name, NC_INT, 1, &value), name);
  });
  for_each_flag(state, [&](const char* name, bool flag) {
    const int value = flag ? 1 : 0;
    nc.check(nc_put_att_int(nc.id, NC_GLOBAL, name, NC_INT, 1, &value), name);
  });
  const std::uint32_t checksum = checkpoint_checksum(state, parameters_text, EHLSIM_VERSION);
  nc.check(nc_put_att_uint(nc.id, NC_GLOBAL, kChecksumAttribute, NC_UINT, 1, &checksum),
           kChecksumAttribute);

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

}  // namespace

void write_checkpoint(const std::filesystem::path& path, const ImpactState& state,
                      const nlohmann::json& parameters) {
  PartialFile file(path);
  write_in_child(file.part_path(), "write checkpoint",
                 [&] { write_checkpoint_file(file.part_path(), state, parameters); });
  file.commit();
}

Checkpoint read_checkpoint(const std::filesystem::path& path) {
  require_netcdf4_file(path, "read checkpoint");
  NcFile nc(path, "read checkpoint");
  nc.check(nc_open(netcdf_path(path).c_str(), NC_NOWRITE, &nc.id), "nc_open");
  const CheckpointReader in{nc, path};
  if (!in.has_attribute("title", NC_CHAR) || read_text_attribute(nc, "title") != kFormatName) {
    throw std::runtime_error(fmt::format("'{}' is not an ehlsim checkpoint (no \"{}\" title)",
                                         path.string(), kFormatName));
  }
  // A checkpoint by its title: a version that is missing or of another type is
  // the field's fault (it was blamed on the title).
  const int version = in.scalar<int>("format_version");
  if (version != kFormatVersion) {
    in.fail("format_version",
            fmt::format("is {}; this ehlsim reads version {} only (checkpoints of other versions "
                        "cannot be continued: run the case again from the start)",
                        version, kFormatVersion));
  }
  Checkpoint c;
  c.revision =
      in.has_attribute("ehlsim_revision", NC_CHAR) ? in.text("ehlsim_revision") : "unknown";
  const std::string parameters_text = in.text("ehlsim_parameters");
  try {
    c.parameters = nlohmann::json::parse(parameters_text);
  } catch (const nlohmann::json::exception&) {
    in.fail("ehlsim_parameters", "is not valid JSON");
  }
  ImpactState& s = c.state;
  for_each_scalar(s, [&](const char* name, double& value) { value = in.scalar<double>(name); });
  for_each_integer(s, [&](const char* name, int& value) { value = in.scalar<int>(name); });
  for_each_flag(s, [&](const char* name, bool& flag) { flag = in.flag(name); });
  const CheckpointGrid layout = checkpoint_grid(in, c.parameters);
  const Grid2D grid(layout.n, layout.half_width);
  for_each_field(s, [&](const char* name, const char*, Field& f) {
    const int var = in.field_variable(name, layout.n);
    f = Field(grid);
    nc.check(nc_get_var_double(nc.id, var, f.data()), name);
  });
  check_plausible(in, s, layout);
  const std::uint32_t stored = in.scalar<std::uint32_t>(kChecksumAttribute);
  if (stored != checkpoint_checksum(s, parameters_text, in.text("ehlsim_version"))) {
    throw std::runtime_error(fmt::format(
        "checkpoint {}: checksum mismatch: the file is corrupt (its data do not match the "
        "CRC-32 it was written with)",
        path.string()));
  }
  return c;
}

Checkpoint read_untrusted_checkpoint(const std::filesystem::path& path) {
  pre_read_in_child(path, "read checkpoint", [&path] { (void)read_checkpoint(path); });
  return read_checkpoint(path);
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
                        "the same case: only {} may change, solver.face_mean excepted)",
                        dotted(it.key()), value_now, file, value_saved, kRestartMayChange),
            dotted(it.key()));
      }
    }
  }
}

}  // namespace ehlsim
