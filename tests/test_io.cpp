// The io component: the atomic writers (CSV, NetCDF, JSON), the readers of
// checkpoints and fields, the progress line, the RunOutput observer, the run
// directory transaction and its lock, the memory guard, the thread budget and
// the signal flag.
#include <fcntl.h>
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <netcdf.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <chrono>
#include <climits>
#include <cmath>
#include <csignal>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <span>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "config/Parameters.hpp"
#include "config/RollingParameters.hpp"
#include "dynamics/DryHertz.hpp"
#include "grid/Grid.hpp"
#include "impact/ImpactConfig.hpp"
#include "impact/Scaling.hpp"
#include "io/AtomicFile.hpp"
#include "io/Checkpoint.hpp"
#include "io/FieldReader.hpp"
#include "io/FieldWriter.hpp"
#include "io/Interrupt.hpp"
#include "io/IsolatedIo.hpp"
#include "io/MemoryGuard.hpp"
#include "io/NetcdfStatus.hpp"
#include "io/ProgramInfo.hpp"
#include "io/ProgressLine.hpp"
#include "io/RangeCheckedJson.hpp"
#include "io/RunDirectory.hpp"
#include "io/RunOutput.hpp"
#include "io/SpikeWriter.hpp"
#include "io/ThreadBudget.hpp"
#include "io/TimeSeriesWriter.hpp"
#include "rheology/Lubricant.hpp"
#include "support/CheckpointDamage.hpp"
#include "support/SteelBall.hpp"
#include "support/TempDir.hpp"
#include "support/TestPaths.hpp"
#include "support/TextFiles.hpp"

namespace ehlsim {
namespace {

namespace fs = std::filesystem;

using ehlsim::testing::library_crash;
using ehlsim::testing::read_file;
using ehlsim::testing::source_dir;
using ehlsim::testing::TempDir;
using ehlsim::testing::write_file;

std::vector<std::string> files_in(const fs::path& dir) {
  std::vector<std::string> names;
  for (const auto& entry : fs::directory_iterator(dir))
    names.push_back(entry.path().filename().string());
  std::sort(names.begin(), names.end());
  return names;
}

// ---------------------------------------------------------------------------
// Writers
// ---------------------------------------------------------------------------

/// The time of step `step` in the spike tests.
double spike_time(int step) { return 0.05 * step; }

StepRecord record(int step, double T) {
  StepRecord r;
  r.step = step;
  r.T = T;
  r.Delta = 1.0 - T;
  r.dDelta_dT = -1.0;
  r.force = 0.1 * step;
  r.h_center = 1.0 / 3.0;
  r.h_min = 0.25;
  r.p_center = 2.0 / 3.0;
  r.p_max = 1.5;
  r.cycles = step + 2;
  r.residual = 1.234567890123e-9;
  return r;
}

namespace {

/// The ConfigError of parse_range_checked_json on `text`, or "" if none.
std::string json_error(const std::string& text) {
  std::istringstream in(text);
  try {
    (void)ehlsim::parse_range_checked_json(in, "f.json");
  } catch (const ehlsim::ConfigError& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(RangeCheckedJson, ANumberOutOfTheRangeOfADoubleIsNamedWithItsKey) {
  // The parser read 1e-400 as 0 without a word, and refused 1e400 without
  // naming the key.
  EXPECT_EQ(json_error(R"({"parameters": {"spike": {"min_prominence": 1e-400}}})"),
            "cannot read 'f.json': parameters.spike.min_prominence = 1e-400 " +
                ehlsim::double_underflow_reason());
  EXPECT_EQ(json_error(R"({"a": [1, {"b": [2, -1E400]}]})"),
            "cannot read 'f.json': a[1].b[1] = -1E400 " + ehlsim::double_overflow_reason());
  EXPECT_EQ(json_error("-2.5e-999"),
            "cannot read 'f.json': the value = -2.5e-999 " + ehlsim::double_underflow_reason());
  // Zero written as such, and the smallest doubles, are numbers.
  for (const char* fine : {"0.0e-500", "-0.0", "4.9e-324", "1.7e308"}) {
    std::istringstream in(fmt::format(R"({{"x": [{{}}, [], {}]}})", fine));
    const nlohmann::json j = ehlsim::parse_range_checked_json(in, "f.json");
    EXPECT_EQ(j.at("x").at(2).get<double>(), std::strtod(fine, nullptr)) << fine;
  }
  // The rest of the document as the parser reads it.
  std::istringstream in(R"({"s": "t", "n": null, "b": true, "i": -3, "u": 18446744073709551615})");
  EXPECT_EQ(ehlsim::parse_range_checked_json(in, "f.json"), nlohmann::json::parse(in.str()));
  // Text that is no JSON: the parser's message, naming the file.
  EXPECT_EQ(json_error(R"({"a": })").rfind("cannot read 'f.json': [json.exception.parse_error", 0),
            0u);
  EXPECT_NE(json_error("{} x").find("parse_error"), std::string::npos);
}

TEST(Writers, TimeSeriesHeaderRowsAndAtomicRename) {
  TempDir dir;
  const fs::path path = dir / "timeseries.csv";
  {
    TimeSeriesWriter w(path);
    w.append(record(1, 0.5));
    w.append(record(2, 1.0));
    EXPECT_TRUE(fs::exists(dir / "timeseries.csv.part"));
    EXPECT_FALSE(fs::exists(path));
    w.commit();
    EXPECT_EQ(w.rows(), 2u);
  }
  EXPECT_EQ(files_in(dir.path()), std::vector<std::string>{"timeseries.csv"});
  EXPECT_EQ(read_file(path),
            "T,Delta,dDelta_dT,force,h_center,h_min,p_center,p_max,cycles,residual,attempts,work\n"
            "0.5,0.5,-1,0.1,0.3333333333,0.25,0.6666666667,1.5,3,1.23456789e-09,1,0\n"
            "1,0,-1,0.2,0.3333333333,0.25,0.6666666667,1.5,4,1.23456789e-09,1,0\n");
}

TEST(Writers, NothingLeftWhenNotCommitted) {
  TempDir dir;
  try {
    TimeSeriesWriter series(dir / "timeseries.csv");
    FieldWriter fields(dir / "fields.nc", Grid2D(9, 1.5),
                       effective_parameters_json(ImpactConfig{}));
    series.append(record(1, 0.5));
    Grid2D grid(9, 1.5);
    fields.append(0.5, Field(grid, 1.0), Field(grid, 2.0));
    EXPECT_EQ(files_in(dir.path()),
              (std::vector<std::string>{"fields.nc.part", "timeseries.csv.part"}));
    throw std::runtime_error("solver failed");
  } catch (const std::runtime_error&) {
  }
  EXPECT_TRUE(files_in(dir.path()).empty());
}

TEST(Writers, WriteJsonAtomic) {
  TempDir dir;
  const nlohmann::json j = {{"a", 1}, {"b", {1.5, 2.5}}};
  write_json_atomic(dir / "run.json", j);
  EXPECT_EQ(files_in(dir.path()), std::vector<std::string>{"run.json"});
  EXPECT_EQ(nlohmann::json::parse(read_file(dir / "run.json")), j);
  EXPECT_THROW(write_json_atomic(dir / "missing" / "run.json", j), std::runtime_error);
  EXPECT_EQ(files_in(dir.path()), std::vector<std::string>{"run.json"});
}

std::string text_attribute(int ncid, int var, const char* name) {
  std::size_t length = 0;
  if (nc_inq_attlen(ncid, var, name, &length) != NC_NOERR) return "<missing>";
  std::string value(length, '\0');
  nc_get_att_text(ncid, var, name, value.data());
  return value;
}

TEST(ProgramInfo, NamesTheCommitItWasBuiltFromAndWhatWithIt) {
  // Outputs of another revision, compiler or FFTW may differ in their last
  // bits: each names the binary that wrote it.
  const std::string revision(source_revision());
  ASSERT_FALSE(revision.empty());
  EXPECT_EQ(program_text(), "ehlsim " EHLSIM_VERSION " (revision " + revision + ")");
  const nlohmann::json program = program_json("impact");
  EXPECT_EQ(program.at("revision"), revision);
  EXPECT_EQ(program.at("command"), "impact");
  EXPECT_EQ(program.at("version"), EHLSIM_VERSION);
  const nlohmann::json& build = program.at("build");
  EXPECT_EQ(build.at("fftw").get<std::string>().rfind("fftw-3.", 0), 0u) << build.dump();
  const std::string netcdf = build.at("netcdf");
  EXPECT_EQ(netcdf.rfind("4.", 0), 0u) << build.dump();
  EXPECT_EQ(netcdf.find(' '), std::string::npos) << "the version alone: " << netcdf;
  EXPECT_FALSE(build.at("compiler").get<std::string>().empty());
  EXPECT_FALSE(build.at("type").get<std::string>().empty());
  // Built from a git checkout: a commit of it, not "unknown".
  const fs::path source = ehlsim::testing::source_dir();
  const std::string git = "git -C '" + source.string() + "' ";
  if (std::system((git + "rev-parse HEAD > /dev/null 2>&1").c_str()) != 0)
    GTEST_SKIP() << "no git checkout (or no git) to check the revision against";
  constexpr std::string_view kDirty = "-dirty";
  std::string commit = revision;
  if (commit.ends_with(kDirty)) commit.resize(commit.size() - kDirty.size());
  const std::string command = git + "cat-file -e '" + commit + "^{commit}' 2> /dev/null";
  EXPECT_EQ(std::system(command.c_str()), 0) << "no commit " << commit << " in " << source;
}

TEST(Writers, NetcdfRoundTrip) {
  TempDir dir;
  const Grid2D grid(9, 1.5);
  const ImpactConfig config =
      load_config(std::nullopt, {"case.M=20", "grid.points=9", "solver.coarsest_points=5"});
  Field P(grid);
  Field H(grid);
  for (int j = 0; j < grid.n; ++j) {
    for (int i = 0; i < grid.n; ++i) {
      P(i, j) = i + 10.0 * j;
      H(i, j) = grid.x(i) * grid.x(i) + 0.5 * grid.y(j);
    }
  }
  {
    FieldWriter w(dir / "fields.nc", grid, effective_parameters_json(config));
    w.append(0.25, P, H);
    Field P2(grid, 7.0);
    w.append(0.5, P2, H);
    w.commit();
    EXPECT_EQ(w.snapshots(), 2u);
  }
  EXPECT_EQ(files_in(dir.path()), std::vector<std::string>{"fields.nc"});

  int ncid = -1;
  ASSERT_EQ(nc_open((dir / "fields.nc").c_str(), NC_NOWRITE, &ncid), NC_NOERR);
  int format = 0;
  nc_inq_format(ncid, &format);
  EXPECT_EQ(format, NC_FORMAT_NETCDF4);
  int dim_time = -1;
  int dim_x = -1;
  std::size_t n_time = 0;
  std::size_t n_x = 0;
  ASSERT_EQ(nc_inq_dimid(ncid, "time", &dim_time), NC_NOERR);
  ASSERT_EQ(nc_inq_dimid(ncid, "x", &dim_x), NC_NOERR);
  nc_inq_dimlen(ncid, dim_time, &n_time);
  nc_inq_dimlen(ncid, dim_x, &n_x);
  EXPECT_EQ(n_time, 2u);
  EXPECT_EQ(n_x, 9u);
  int unlimited = -1;
  nc_inq_unlimdim(ncid, &unlimited);
  EXPECT_EQ(unlimited, dim_time);

  int var = -1;
  ASSERT_EQ(nc_inq_varid(ncid, "P", &var), NC_NOERR);
  std::vector<double> values(2 * grid.size());
  ASSERT_EQ(nc_get_var_double(ncid, var, values.data()), NC_NOERR);
  for (std::size_t k = 0; k < grid.size(); ++k) {
    EXPECT_EQ(values[k], P[k]);
    EXPECT_EQ(values[grid.size() + k], 7.0);
  }
  EXPECT_EQ(text_attribute(ncid, var, "units"), "1");
  int storage = -1;
  std::vector<std::size_t> chunks(3);
  nc_inq_var_chunking(ncid, var, &storage, chunks.data());
  EXPECT_EQ(storage, NC_CHUNKED);
  EXPECT_EQ(chunks, (std::vector<std::size_t>{1, 9, 9}));

  ASSERT_EQ(nc_inq_varid(ncid, "H", &var), NC_NOERR);
  ASSERT_EQ(nc_get_var_double(ncid, var, values.data()), NC_NOERR);
  EXPECT_EQ(values[3 + 9 * 4], H(3, 4));

  EXPECT_EQ(text_attribute(ncid, var, "coordinates"), "time y x");

  ASSERT_EQ(nc_inq_varid(ncid, "time", &var), NC_NOERR);
  std::vector<double> T(2);
  nc_get_var_double(ncid, var, T.data());
  EXPECT_EQ(T, (std::vector<double>{0.25, 0.5}));
  EXPECT_EQ(text_attribute(ncid, var, "axis"), "T");
  EXPECT_EQ(text_attribute(ncid, var, "units"), "1");

  ASSERT_EQ(nc_inq_varid(ncid, "x", &var), NC_NOERR);
  std::vector<double> X(9);
  nc_get_var_double(ncid, var, X.data());
  EXPECT_EQ(X.front(), -1.5);
  EXPECT_EQ(X.back(), 1.5);
  EXPECT_EQ(text_attribute(ncid, var, "units"), "1");
  EXPECT_EQ(text_attribute(ncid, var, "long_name"), "dimensionless coordinate X = x / a*");
  // No axis on x and y: ParaView's CF reader would take them for longitude
  // and latitude and draw the grid on a sphere.
  EXPECT_EQ(text_attribute(ncid, var, "axis"), "<missing>");
  ASSERT_EQ(nc_inq_varid(ncid, "y", &var), NC_NOERR);
  EXPECT_EQ(text_attribute(ncid, var, "axis"), "<missing>");

  EXPECT_EQ(text_attribute(ncid, NC_GLOBAL, "Conventions"), "CF-1.8");
  EXPECT_EQ(text_attribute(ncid, NC_GLOBAL, "source"), program_text());
  EXPECT_EQ(text_attribute(ncid, NC_GLOBAL, "ehlsim_version"), EHLSIM_VERSION);
  EXPECT_EQ(text_attribute(ncid, NC_GLOBAL, "ehlsim_revision"), source_revision());
  EXPECT_EQ(text_attribute(ncid, NC_GLOBAL, "lubricant_viscosity"), "barus");
  EXPECT_EQ(text_attribute(ncid, NC_GLOBAL, "body_elastic"), "true");
  EXPECT_EQ(text_attribute(ncid, NC_GLOBAL, "time_T_end"), "none");
  double M = 0.0;
  ASSERT_EQ(nc_get_att_double(ncid, NC_GLOBAL, "case_M", &M), NC_NOERR);
  EXPECT_EQ(M, 20.0);
  int points = 0;
  ASSERT_EQ(nc_get_att_int(ncid, NC_GLOBAL, "grid_points", &points), NC_NOERR);
  EXPECT_EQ(points, 9);
  EXPECT_EQ(nlohmann::json::parse(text_attribute(ncid, NC_GLOBAL, "ehlsim_parameters")),
            effective_parameters_json(config));
  nc_close(ncid);
}

std::vector<double> double_variable(int ncid, const char* name, std::size_t size) {
  int var = -1;
  std::vector<double> values(size);
  if (nc_inq_varid(ncid, name, &var) != NC_NOERR) return {};
  nc_get_var_double(ncid, var, values.data());
  return values;
}

// The rolling contact's domain, X in [-4.5, 1.5], Y in [-3, 3]: rectangular,
// not centred, one snapshot.  x runs along the rows of the stored (time, y, x).
TEST(Writers, NetcdfRectangularLayout) {
  TempDir dir;
  FieldLayout layout{{-4.5, -3.0, -1.5, 0.0, 1.5}, {-3.0, 0.0, 3.0}, "rolling contact"};
  std::vector<double> P(layout.points());
  for (std::size_t k = 0; k < P.size(); ++k) P[k] = layout.x[k % 5] + 10.0 * layout.y[k / 5];
  const std::vector<double> H(layout.points(), 0.5);
  {
    FieldWriter w(dir / "fields.nc", layout, nlohmann::json::object());
    EXPECT_THROW(w.append(0.0, std::span<const double>(P).first(14), H), std::invalid_argument);
    w.append(0.0, P, H);
    w.commit();
  }
  int ncid = -1;
  ASSERT_EQ(nc_open((dir / "fields.nc").c_str(), NC_NOWRITE, &ncid), NC_NOERR);
  EXPECT_EQ(double_variable(ncid, "x", 5), layout.x);
  EXPECT_EQ(double_variable(ncid, "y", 3), layout.y);
  EXPECT_EQ(double_variable(ncid, "time", 1), std::vector<double>{0.0});
  const std::vector<double> stored = double_variable(ncid, "P", layout.points());
  EXPECT_EQ(stored, P);
  EXPECT_EQ(stored[3 + 5 * 2], 0.0 + 10.0 * 3.0);  // P at X = 0, Y = 3
  EXPECT_EQ(text_attribute(ncid, NC_GLOBAL, "title"), "rolling contact");
  nc_close(ncid);
}

TEST(Writers, NetcdfLayoutNeedsTwoPointsPerAxis) {
  TempDir dir;
  try {
    FieldWriter w(dir / "fields.nc", FieldLayout{{0.0, 1.0}, {}, "empty"},
                  nlohmann::json::object());
    FAIL() << "expected an error";
  } catch (const std::invalid_argument& e) {
    EXPECT_STREQ(e.what(), "FieldWriter: a grid of 2 x 0 points");
  }
  EXPECT_TRUE(files_in(dir.path()).empty());
}

TEST(Writers, NetcdfErrorsNameTheFile) {
  TempDir dir;
  try {
    FieldWriter w(dir / "missing" / "fields.nc", Grid2D(9, 1.5), nlohmann::json::object());
    FAIL() << "expected an error";
  } catch (const std::runtime_error& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("fields.nc.part"), std::string::npos) << message;
    // The system's reason, not NetCDF's EACCES for any failed create.
    EXPECT_NE(message.find("nc_create: No such file or directory"), std::string::npos) << message;
  }
}

TEST(Writers, NetcdfWriteErrorsGiveTheSystemsReason) {
  const std::filesystem::path path = "out/fields.nc.part";
  const auto message = [&](int status, int error, const char* what) {
    errno = error;
    try {
      check_netcdf_write(status, "write", path, what);
    } catch (const std::runtime_error& e) {
      EXPECT_EQ(errno, 0);  // cleared for the next call
      return std::string(e.what());
    }
    return std::string("no error");
  };
  const std::string file = "cannot write 'out/fields.nc.part': ";
  EXPECT_EQ(message(NC_EHDFERR, EIO, "nc_close"),
            file + "nc_close (Input/output error): NetCDF: HDF error");
  EXPECT_EQ(message(NC_EHDFERR, 0, "nc_close"), file + "nc_close: NetCDF: HDF error");
  // NetCDF's EACCES for any failed create gives way to errno.
  EXPECT_EQ(message(EACCES, EIO, "nc_create"), file + "nc_create: Input/output error");
  EXPECT_EQ(message(EACCES, EACCES, "nc_create"), file + "nc_create: Permission denied");
  EXPECT_EQ(message(NC_NOERR, ENOENT, "nc_create"), "no error");
  EXPECT_EQ(errno, 0);
}

// ---------------------------------------------------------------------------
// Checkpoints
// ---------------------------------------------------------------------------

/// The effective parameters of the default case on 17^2 points.
nlohmann::json small_case_parameters() {
  return effective_parameters_json(
      load_config(std::nullopt, {"grid.points=17", "solver.coarsest_points=9"}));
}

/// A state a run could have written: step 42 at the parameters' time step on
/// 17^2 points, fields > 0 with a different pattern in each.
ImpactState plausible_state(const nlohmann::json& parameters) {
  const Grid2D grid(17, 1.5);
  const double dT = parameters.at("time").at("dT").get<double>();
  ImpactState s;
  s.step = 42;
  s.ball = {42 * dT, -0.3141592653589793, 0.27182818284590, 1.6180339887};
  s.force = 0.5772156649;
  s.force_before = 0.5772;
  s.had_pressure = true;
  s.summary.steps = 42;
  s.summary.max_force = 2.1;
  s.summary.T_lift_off = std::numeric_limits<double>::quiet_NaN();  // no lift-off yet
  s.summary.rebound_speed = std::numeric_limits<double>::quiet_NaN();
  s.summary.impulse = 1.0 / 3.0;
  s.summary.unconverged_steps = 3;
  s.summary.retried_steps = 5;
  double phase = 0.0;
  for (Field* f : {&s.P, &s.P_before, &s.P_before2, &s.P_before3, &s.rhoH, &s.rhoH_before}) {
    *f = Field(grid);
    phase += 1.0;
    double x = phase;
    for (std::size_t k = 0; k < f->size(); ++k, x += 0.37) (*f)[k] = 0.1 + std::fabs(std::sin(x));
  }
  return s;
}

/// read_checkpoint's error for `path`: its message, "" if it reads.
std::string checkpoint_error(const fs::path& path) {
  try {
    (void)read_checkpoint(path);
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "";
}

TEST(Checkpoint, RoundTripIsExact) {
  TempDir dir;
  const nlohmann::json parameters = small_case_parameters();
  ImpactState s = plausible_state(parameters);
  s.P_before[5] = 1e-300;            // every bit must survive
  s.attempts = {2, 0, 2, true};      // a probe of attempt 2 after two failed ones
  s.splits = {{1, 4, 1, false}, 2};  // in halves, a fifth step before the next probe
  const fs::path path = dir / "checkpoint.nc";
  write_checkpoint(path, s, parameters);
  EXPECT_FALSE(fs::exists(path.string() + PartialFile::kSuffix));

  const Checkpoint c = read_checkpoint(path);
  EXPECT_EQ(c.parameters, parameters);
  const ImpactState& r = c.state;
  EXPECT_EQ(r.step, 42);
  EXPECT_EQ(r.ball.T, s.ball.T);
  EXPECT_EQ(r.ball.Delta, s.ball.Delta);
  EXPECT_EQ(r.ball.V, s.ball.V);
  EXPECT_EQ(r.ball.A, s.ball.A);
  EXPECT_EQ(r.force, s.force);
  EXPECT_EQ(r.force_before, s.force_before);
  EXPECT_TRUE(r.had_pressure);
  EXPECT_EQ(r.summary.steps, 42);
  EXPECT_EQ(r.summary.max_force, 2.1);
  EXPECT_TRUE(std::isnan(r.summary.T_lift_off));
  EXPECT_EQ(r.summary.impulse, 1.0 / 3.0);
  EXPECT_EQ(r.summary.unconverged_steps, 3);
  EXPECT_EQ(r.summary.retried_steps, 5);
  EXPECT_EQ(r.attempts.first, 2);
  EXPECT_EQ(r.attempts.streak, 0);
  EXPECT_EQ(r.attempts.failed_probes, 2);
  EXPECT_TRUE(r.attempts.probing);
  EXPECT_EQ(r.splits.begin.first, 1);
  EXPECT_EQ(r.splits.begin.streak, 4);
  EXPECT_EQ(r.splits.begin.failed_probes, 1);
  EXPECT_FALSE(r.splits.begin.probing);
  EXPECT_EQ(r.splits.last_needed, 2);
  const std::array<std::pair<const Field*, const Field*>, 6> fields = {
      {{&r.P, &s.P},
       {&r.P_before, &s.P_before},
       {&r.P_before2, &s.P_before2},
       {&r.P_before3, &s.P_before3},
       {&r.rhoH, &s.rhoH},
       {&r.rhoH_before, &s.rhoH_before}}};
  for (const auto& [read, written] : fields) {
    ASSERT_EQ(read->n(), 17);
    for (std::size_t k = 0; k < read->size(); ++k) ASSERT_EQ((*read)[k], (*written)[k]) << k;
  }
}

TEST(Checkpoint, ReadingSomethingElseNamesTheFile) {
  TempDir dir;
  const fs::path fields = dir / "fields.nc";
  {
    FieldWriter w(fields, Grid2D(9, 1.5), nlohmann::json::object());
    w.commit();
  }
  for (const fs::path& path : {fields, dir / "missing.nc"}) {
    try {
      (void)read_checkpoint(path);
      FAIL() << "expected an error for " << path;
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find(path.string()), std::string::npos) << e.what();
    }
  }
  // A FIFO without a writer would block the open for ever; a directory or a
  // device is no checkpoint either: refused before it is opened.
  const fs::path fifo = dir / "fifo";
  ASSERT_EQ(mkfifo(fifo.c_str(), 0600), 0);
  for (const fs::path& path : {fifo, dir.path(), fs::path("/dev/zero")}) {
    try {
      (void)read_checkpoint(path);
      FAIL() << "expected an error for " << path;
    } catch (const std::runtime_error& e) {
      EXPECT_EQ(std::string(e.what()), "cannot read checkpoint '" + path.string() +
                                           "': not a regular file (a directory, FIFO or device)");
    }
  }
}

TEST(Checkpoint, DamagedFilesNameTheFileAndTheField) {
  TempDir dir;
  const nlohmann::json parameters = small_case_parameters();
  const ImpactState good = plausible_state(parameters);
  const fs::path path = dir / "checkpoint.nc";
  const auto fresh = [&] { write_checkpoint(path, good, parameters); };
  const std::string prefix = "checkpoint " + path.string() + ": ";

  fresh();
  ASSERT_EQ(checkpoint_error(path), "");
  // The probes of issue 10: 16 flipped bytes, T = NaN, step = INT_MAX.
  ehlsim::testing::flip_16_bytes_of(path, good.rhoH, 40);
  EXPECT_EQ(checkpoint_error(path),
            prefix +
                "checksum mismatch: the file is corrupt (its data do not match the CRC-32 "
                "it was written with)");
  fresh();
  ehlsim::testing::rewrite_attribute(path, "T", std::numeric_limits<double>::quiet_NaN());
  EXPECT_EQ(checkpoint_error(path), prefix + "field 'T' is not finite (nan)");
  fresh();
  ehlsim::testing::rewrite_attribute(path, "step", std::numeric_limits<int>::max());
  EXPECT_EQ(checkpoint_error(path), prefix + "field 'step' = 2147483647: must be in [1, 10000000]");
  fresh();
  ehlsim::testing::rewrite_attribute(path, "step", 1000);
  EXPECT_EQ(checkpoint_error(path).rfind(prefix + "field 'step' = 1000 does not match T = "), 0u)
      << checkpoint_error(path);
  // A value that is plausible but not the one written: only the checksum sees it.
  fresh();
  ehlsim::testing::rewrite_attribute(path, "force", 5.44);
  EXPECT_NE(checkpoint_error(path).find("checksum mismatch"), std::string::npos);
  // An older format.
  fresh();
  ehlsim::testing::rewrite_attribute(path, "format_version", 2);
  EXPECT_EQ(checkpoint_error(path),
            prefix +
                "field 'format_version' is 2; this ehlsim reads version 9 only (checkpoints "
                "of other versions cannot be continued: run the case again from the start)");
  // A version of another type, or none, is the field's fault, not the title's.
  fresh();
  ehlsim::testing::rewrite_attribute(path, "format_version", 9.0);
  EXPECT_EQ(checkpoint_error(path),
            prefix + "field 'format_version' is not a single value of its type");
  fresh();
  ehlsim::testing::delete_attribute(path, "format_version");
  EXPECT_EQ(checkpoint_error(path), prefix + "field 'format_version' is missing");
  // A flag is 0 or 1: 7 was read as true and passed the checksum.
  for (const char* flag : {"had_pressure", "attempts_probing", "splits_probing"}) {
    for (const int value : {7, -1}) {
      fresh();
      ehlsim::testing::rewrite_attribute(path, flag, value);
      EXPECT_EQ(checkpoint_error(path),
                prefix + fmt::format("field '{}' = {}: must be 0 or 1", flag, value));
    }
  }
}

TEST(Checkpoint, ImplausibleStatesAreRefusedEvenWithAValidChecksum) {
  TempDir dir;
  const nlohmann::json parameters = small_case_parameters();
  const fs::path path = dir / "checkpoint.nc";
  const std::string prefix = "checkpoint " + path.string() + ": field ";
  const auto error_of = [&](const std::function<void(ImpactState&)>& damage) {
    ImpactState s = plausible_state(parameters);
    damage(s);
    write_checkpoint(path, s, parameters);
    return checkpoint_error(path);
  };
  EXPECT_EQ(error_of([](ImpactState& s) { s.P(3, 4) = -0.5; }),
            prefix + "'P' is negative (-0.5) at point (3, 4): a pressure is >= 0");
  // Two faults: the first point row by row (j, then i) is the one named.
  EXPECT_EQ(error_of([](ImpactState& s) {
              s.P(3, 4) = -0.5;
              s.P(2, 5) = std::numeric_limits<double>::quiet_NaN();
              s.P(7, 4) = std::numeric_limits<double>::infinity();
            }),
            prefix + "'P' is negative (-0.5) at point (3, 4): a pressure is >= 0");
  EXPECT_EQ(error_of([](ImpactState& s) { s.rhoH(5, 6) = -1e-3; }),
            prefix + "'rhoH' is negative (-0.001) at point (5, 6): a film is >= 0");
  EXPECT_EQ(error_of([](ImpactState& s) { s.rhoH_before(0, 6) = -1.0; }), "")
      << "the film on the boundary is not a solved value";
  EXPECT_EQ(
      error_of([](ImpactState& s) { s.P_before(2, 2) = std::numeric_limits<double>::infinity(); }),
      prefix + "'P_before' is not finite (inf) at point (2, 2)");
  EXPECT_EQ(error_of([](ImpactState& s) { s.force = std::numeric_limits<double>::quiet_NaN(); }),
            prefix + "'force' is not finite (nan)");
  EXPECT_EQ(error_of([](ImpactState& s) { s.summary.steps = 41; }),
            prefix + "'summary_steps' = 41 differs from step = 42");
  EXPECT_EQ(error_of([](ImpactState& s) { s.summary.retried_steps = -1; }),
            prefix + "'summary_retried_steps' = -1: must be in [0, step = 42]");
  EXPECT_EQ(error_of([](ImpactState& s) { s.attempts.first = kMaxRetries + 1; }),
            prefix + "'attempts_first' = 4: must be in [0, 3]");
  EXPECT_EQ(error_of([](ImpactState& s) { s.attempts.streak = kStepsBeforeLighterAttempt; }),
            prefix + "'attempts_streak' = 3: must be in [0, 2]");
  EXPECT_EQ(error_of([](ImpactState& s) {
              s.attempts.failed_probes = 1;
              s.attempts.streak = 2 * kStepsBeforeLighterAttempt;
            }),
            prefix + "'attempts_streak' = 6: must be in [0, 5]");
  EXPECT_EQ(error_of([](ImpactState& s) { s.attempts.failed_probes = kMaxProbeBackoff + 1; }),
            prefix + "'attempts_failed_probes' = 4: must be in [0, 3]");
  EXPECT_EQ(error_of([](ImpactState& s) {
              s.attempts.first = kMaxRetries;
              s.attempts.probing = true;
            }),
            prefix +
                "'attempts_probing' = 1 with attempts_first = 3 and attempts_streak = 0: a "
                "probe needs them below 3 and at 0");
  EXPECT_EQ(error_of([](ImpactState& s) { s.splits.begin.first = kMaxSplitDepth + 1; }),
            prefix + "'splits_first' = 6: must be in [0, 5]");
  EXPECT_EQ(error_of([](ImpactState& s) { s.splits.last_needed = -1; }),
            prefix + "'splits_last_needed' = -1: must be in [0, 5]");
  EXPECT_EQ(error_of([](ImpactState& s) {
              s.splits.begin.first = 1;
              s.splits.begin.streak = 1;
              s.splits.begin.probing = true;
            }),
            prefix +
                "'splits_probing' = 1 with splits_first = 1 and splits_streak = 1: a "
                "probe needs them below 5 and at 0");
  EXPECT_EQ(error_of([](ImpactState& s) {
              s.step = 0;
              s.summary.steps = 0;
            }),
            prefix + "'step' = 0: must be in [1, 10000000]");
  // 2^31 - 1 (with a forged checksum) overflowed the next step's number.
  EXPECT_EQ(error_of([](ImpactState& s) {
              s.step = std::numeric_limits<int>::max();
              s.summary.steps = s.step;
            }),
            prefix + "'step' = 2147483647: must be in [1, 10000000]");
  EXPECT_EQ(error_of([](ImpactState& s) { s.force_before = -1e10; }),
            prefix + "'force_before' = -1e+10: a film force is >= 0");
  // The grid of the parameters must be the one of the fields.
  nlohmann::json other = parameters;
  other["grid"]["points"] = 33;
  write_checkpoint(path, plausible_state(parameters), other);
  EXPECT_EQ(checkpoint_error(path),
            prefix + "'x' (dimension) has 17 points; its parameters say grid.points = 33");
}

TEST(Checkpoint, RestartMustContinueTheSameCase) {
  const nlohmann::json saved = effective_parameters_json(load_config(std::nullopt, {}));
  const auto parameters = [](const std::vector<std::string>& overrides) {
    return effective_parameters_json(load_config(std::nullopt, overrides));
  };
  // Solver, output and spike settings and the end time may change ...
  EXPECT_NO_THROW(check_restart_compatible(
      saved,
      parameters({"solver.switch_ratio=10", "solver.max_cycles=40", "output.snapshot_every=1",
                  "spike.filter=\"gaussian\"", "time.T_end=3.5", "output.checkpoint_every=5"}),
      "c.nc"));
  // ... the case, the grid, the time step and the discrete flux may not.
  const std::vector<std::pair<std::string, std::string>> changes = {
      {"case.M=20", "case.M"},
      {"grid.points=129", "grid.points"},
      {"time.dT=0.01", "time.dT"},
      {"body.elastic=false", "body.elastic"},
      {"time.Delta0=0.5", "time.Delta0"},
      {"solver.face_mean=\"harmonic\"", "solver.face_mean"},
  };
  for (const auto& [change, key] : changes) {
    try {
      check_restart_compatible(saved, parameters({change}), "c.nc");
      FAIL() << "expected an error for " << change;
    } catch (const ConfigError& e) {
      EXPECT_EQ(e.key(), key) << e.what();
      EXPECT_NE(std::string(e.what()).find("checkpoint 'c.nc'"), std::string::npos) << e.what();
    }
  }
}

// ---------------------------------------------------------------------------
// Memory guard
// ---------------------------------------------------------------------------

TEST(MemoryGuard, EstimateGrowsWithTheGridAndTheFullDomain) {
  const auto estimate = [](const std::vector<std::string>& overrides) {
    return estimate_run_memory(load_config(std::nullopt, overrides));
  };
  const MemoryEstimate small = estimate({"grid.points=129"});
  const MemoryEstimate large = estimate({"grid.points=513"});
  const MemoryEstimate full = estimate({"grid.points=513", "solver.symmetry=\"off\""});
  // The grid-dependent parts grow with the points: 16 times from 129^2 to 513^2 (+-1 level).
  EXPECT_NEAR(large.grid_mb / small.grid_mb, 16.0, 0.5);
  EXPECT_NEAR(large.solver_mb / small.solver_mb, 16.0, 0.5);
  // The full domain holds 4 times the points of the quadrant on every level.
  EXPECT_NEAR(full.solver_mb / large.solver_mb, 4.0, 0.1);
  EXPECT_EQ(full.grid_mb, large.grid_mb);
  // The measured peaks of docs/performance.md are below the estimate.
  EXPECT_GT(small.total_mb(), 25.6);
  EXPECT_GT(large.total_mb(), 60.0);
  EXPECT_GT(full.total_mb(), 107.4);
  EXPECT_GT(estimate({"grid.points=4097"}).total_mb(), 2000.0);
  const MemoryEstimate with_checkpoints =
      estimate({"grid.points=513", "output.checkpoint_every=5"});
  EXPECT_GT(with_checkpoints.grid_mb, large.grid_mb);
}

TEST(MemoryGuard, RefusesWhatExceedsTheLimitNamingTheKeys) {
  const ImpactConfig huge =
      load_config(std::nullopt, {"grid.points=4097", "solver.memory_limit_mb=100"});
  try {
    (void)check_run_memory(huge, 1e9);
    FAIL() << "expected a refusal";
  } catch (const ConfigError& e) {
    EXPECT_EQ(e.key(), "grid.points");
    const std::string message = e.what();
    EXPECT_EQ(message.rfind("grid.points = 4097: the run needs about ", 0), 0u) << message;
    EXPECT_NE(message.find("MB of memory (estimate), more than the limit solver.memory_limit_mb = "
                           "100: use fewer grid.points, or raise solver.memory_limit_mb"),
              std::string::npos)
        << message;
  }
  // Without a given limit, the machine's available memory is the limit.
  const ImpactConfig plain = load_config(std::nullopt, {"grid.points=4097"});
  try {
    (void)check_run_memory(plain, 500.0);
    FAIL() << "expected a refusal";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("more than the 500 MB this machine has available "
                                         "(MemAvailable in /proc/meminfo; solver.memory_limit_mb "
                                         "sets another limit)"),
              std::string::npos)
        << e.what();
  }
  const MemoryBudget fits = check_run_memory(plain, 1e6);
  EXPECT_EQ(fits.limit_source, "MemAvailable");
  EXPECT_EQ(fits.limit_mb, 1e6);
  // A given limit replaces the available memory, in both directions.
  const ImpactConfig generous =
      load_config(std::nullopt, {"grid.points=4097", "solver.memory_limit_mb=1e6"});
  EXPECT_EQ(check_run_memory(generous, 500.0).limit_source, "solver.memory_limit_mb");
  const nlohmann::json j = memory_json(fits);
  EXPECT_GT(j.at("estimate_mb").get<double>(), 2000.0);
  EXPECT_EQ(j.at("limit_source"), "MemAvailable");
  EXPECT_TRUE(j.at("limit_mb").is_null()) << "the available memory is not reproducible";
  EXPECT_EQ(memory_json(check_run_memory(generous, 500.0)).at("limit_mb"), 1e6);
  EXPECT_TRUE(j.at("parts_mb").contains("solver"));
}

TEST(MemoryGuard, RollingEstimateGrowsWithTheGridAndStaysAboveTheMeasuredPeak) {
  const auto config = [](int points) {
    return load_rolling_config(std::nullopt, {"grid.points=" + std::to_string(points)});
  };
  const auto estimate = [&](int points) { return estimate_rolling_memory(config(points)); };
  const MemoryEstimate small = estimate(129);
  const MemoryEstimate large = estimate(513);
  // Every level is the full grid: 16 times the points from 129^2 to 513^2 (+-1 level).
  EXPECT_NEAR(large.grid_mb / small.grid_mb, 16.0, 0.5);
  EXPECT_NEAR(large.solver_mb / small.solver_mb, 16.0, 0.5);
  // The levels of the full grid hold about 4/3 of its points, not the impact
  // quadrant's 1/3.
  EXPECT_GT(large.solver_mb, large.grid_mb);
  // Peak RSS measured 2026-11-23 (`/usr/bin/time -f %M build/apps/ehlsim
  // rolling --quiet --set grid.points=N`, 1 and 2 threads; docs/performance.md,
  // "Memory"): 26.1 MB on 129^2, 35.4 on 257^2, 89.5 on 513^2, 306.3 on 1025^2.
  EXPECT_GT(small.total_mb(), 26.1);
  EXPECT_GT(estimate(257).total_mb(), 35.4);
  EXPECT_GT(large.total_mb(), 89.5);
  EXPECT_GT(estimate(1025).total_mb(), 306.3);
  EXPECT_LT(estimate(257).total_mb(), large.total_mb());
  EXPECT_LT(large.total_mb(), estimate(1025).total_mb());
  // The check is the impact's: the same limit, key and message.
  RollingConfig huge = config(4097);
  huge.memory_limit_mb = 100.0;
  try {
    (void)check_run_memory(huge, 1e9);
    FAIL() << "expected a refusal";
  } catch (const ConfigError& e) {
    EXPECT_EQ(e.key(), "grid.points");
    EXPECT_EQ(std::string(e.what()).rfind("grid.points = 4097: the run needs about ", 0), 0u)
        << e.what();
  }
  EXPECT_EQ(check_run_memory(config(129), 1e6).limit_source, "MemAvailable");
}

TEST(MemoryGuard, ReadsTheAvailableMemoryOfThisMachine) {
  const std::optional<double> available = available_memory_mb();
  ASSERT_TRUE(available.has_value());
  EXPECT_GT(*available, 0.0);
}

// ---------------------------------------------------------------------------
// Damaged NetCDF files (fuzz/, docs/validation.md "Fuzzing and sanitizers"):
// the readers answer with a std::runtime_error naming the file, never a crash
// or another exception.
// ---------------------------------------------------------------------------

/// A checkpoint the readers accept, on a 9^2 grid.
fs::path write_valid_checkpoint(const fs::path& path,
                                nlohmann::json parameters = effective_parameters_json(load_config(
                                    std::nullopt, {"grid.points=9", "solver.coarsest_points=5"}))) {
  const Grid2D grid(9, 1.5);
  ImpactState s;
  s.step = 3;
  s.summary.steps = 3;
  s.ball = {1.125, 0.5, -1.0, 0.0};  // T = step x dT (3 x 0.375)
  for (Field* f : {&s.P, &s.P_before, &s.P_before2, &s.P_before3}) *f = Field(grid, 0.0);
  for (Field* f : {&s.rhoH, &s.rhoH_before}) *f = Field(grid, 1.0);
  write_checkpoint(path, s, parameters);
  return path;
}

/// Runs `change(ncid)` on the open file in define mode.
template <class Change>
void edit_netcdf(const fs::path& path, Change change) {
  int ncid = -1;
  ASSERT_EQ(nc_open(path.c_str(), NC_WRITE, &ncid), NC_NOERR);
  ASSERT_EQ(nc_redef(ncid), NC_NOERR);
  change(ncid);
  ASSERT_EQ(nc_close(ncid), NC_NOERR);
}

/// The message of the std::runtime_error `read` throws ("" if none).
template <class Read>
std::string read_error(Read read) {
  try {
    read();
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "";
}

std::string fields_error(const fs::path& path) {
  return read_error([&] { const FieldReader reader(path); });
}

TEST(DamagedFiles, OnlyNetcdf4IsRead) {
  TempDir dir;
  // A classic-format file: libnetcdf's parser of that format is kept away
  // from untrusted bytes (a 66-byte header made it ask for 2.7 GB).
  const fs::path classic = dir / "classic.nc";
  int ncid = -1;
  ASSERT_EQ(nc_create(classic.c_str(), NC_CLOBBER, &ncid), NC_NOERR);
  ASSERT_EQ(nc_close(ncid), NC_NOERR);
  const fs::path oom =
      source_dir() / "tests" / "fuzz-regressions" / "checkpoint" / "classic-header-asks-2.7GB.nc";
  for (const fs::path& path : {classic, oom, write_file(dir / "empty.nc", "")}) {
    for (const std::string& message : {checkpoint_error(path), fields_error(path)}) {
      const std::string expected = fmt::format("'{}': not a NetCDF-4 file", path.string());
      EXPECT_NE(message.find(expected), std::string::npos) << message;
    }
  }
}

TEST(DamagedFiles, APressureTheFileLostIsNoPressure) {
  // A chunk HDF5 lost (one flipped bit) reads as the fill value 9.97e36:
  // `ehlsim spike` analysed it as a pressure, with exit 0.  Here a third
  // time whose P was never written stands for it.
  TempDir dir;
  const fs::path path = dir / "fields.nc";
  const Grid2D grid(9, 1.5);
  {
    FieldWriter w(path, grid, nlohmann::json::object());
    w.append(0.5, Field(grid, 1.0), Field(grid, 2.0));
    w.append(1.0, Field(grid, 1.5), Field(grid, 2.5));
    w.commit();
  }
  int ncid = -1, time = -1;
  ASSERT_EQ(nc_open(path.c_str(), NC_WRITE, &ncid), NC_NOERR);
  ASSERT_EQ(nc_inq_varid(ncid, "time", &time), NC_NOERR);
  const std::size_t third = 2;
  const double T = 1.5;
  ASSERT_EQ(nc_put_var1_double(ncid, time, &third, &T), NC_NOERR);
  ASSERT_EQ(nc_close(ncid), NC_NOERR);
  const FieldReader reader(path);
  ASSERT_EQ(reader.times().size(), 3u);
  EXPECT_EQ(reader.pressure(1)(4, 4), 1.5);
  const std::string message = read_error([&] { (void)reader.pressure(2); });
  EXPECT_NE(message.find("variable P of snapshot 2 has no data at point (0, 0) (the NetCDF fill "
                         "value 9.96921e+36: a part of the file is lost)"),
            std::string::npos)
      << message;
}

TEST(DamagedFiles, CheckpointAttributeWithSeveralValues) {
  TempDir dir;
  const fs::path path = write_valid_checkpoint(dir / "checkpoint.nc");
  ASSERT_EQ(checkpoint_error(path), "");
  // nc_get_att_double would write three doubles into the one T of the state.
  edit_netcdf(path, [](int ncid) {
    const std::array<double, 3> values = {1.0, 2.0, 3.0};
    ASSERT_EQ(nc_put_att_double(ncid, NC_GLOBAL, "T", NC_DOUBLE, 3, values.data()), NC_NOERR);
  });
  EXPECT_NE(checkpoint_error(path).find("field 'T' is not a single value of its type"),
            std::string::npos)
      << checkpoint_error(path);
}

TEST(DamagedFiles, CheckpointFieldOfAnotherShape) {
  TempDir dir;
  const fs::path path = write_valid_checkpoint(dir / "checkpoint.nc");
  // P on (z, x) with 20 x 9 values: nc_get_var would fill 180 into a field of 81.
  edit_netcdf(path, [](int ncid) {
    int var = -1;
    int dim_x = -1;
    std::array<int, 2> dims{};
    ASSERT_EQ(nc_inq_varid(ncid, "P", &var), NC_NOERR);
    ASSERT_EQ(nc_rename_var(ncid, var, "P_saved"), NC_NOERR);
    ASSERT_EQ(nc_inq_dimid(ncid, "x", &dim_x), NC_NOERR);
    ASSERT_EQ(nc_def_dim(ncid, "z", 20, &dims[0]), NC_NOERR);
    dims[1] = dim_x;
    ASSERT_EQ(nc_def_var(ncid, "P", NC_DOUBLE, 2, dims.data(), &var), NC_NOERR);
  });
  EXPECT_NE(checkpoint_error(path).find("field 'P' has 20 x 9 values; the grid has 9 x 9 points"),
            std::string::npos)
      << checkpoint_error(path);
}

TEST(DamagedFiles, CheckpointGridMustBePositive) {
  TempDir dir;
  nlohmann::json parameters = effective_parameters_json(
      load_config(std::nullopt, {"grid.points=9", "solver.coarsest_points=5"}));
  parameters["grid"]["half_width"] = 0.0;
  const fs::path path = write_valid_checkpoint(dir / "checkpoint.nc", parameters);
  EXPECT_NE(checkpoint_error(path).find("has an impossible grid or time step (grid.points = 9, "
                                        "grid.half_width = 0"),
            std::string::npos)
      << checkpoint_error(path);
}

TEST(DamagedFiles, FieldsCoordinateAndShapes) {
  TempDir dir;
  const auto write_fields = [&](const std::string& name) {
    const fs::path path = dir / name;
    FieldWriter w(path, Grid2D(9, 1.5), nlohmann::json::object());
    w.append(0.5, Field(Grid2D(9, 1.5), 0.25), Field(Grid2D(9, 1.5), 1.0));
    w.commit();
    return path;
  };
  const fs::path valid = write_fields("valid.nc");
  ASSERT_EQ(fields_error(valid), "");
  // x from +1.5: the grid it implies has no positive half-width.
  const fs::path flipped = write_fields("flipped.nc");
  edit_netcdf(flipped, [](int ncid) {
    int var = -1;
    ASSERT_EQ(nc_enddef(ncid), NC_NOERR);
    ASSERT_EQ(nc_inq_varid(ncid, "x", &var), NC_NOERR);
    std::array<double, 9> X{};
    for (std::size_t i = 0; i < X.size(); ++i) X[i] = 1.5 - 0.375 * static_cast<double>(i);
    ASSERT_EQ(nc_put_var_double(ncid, var, X.data()), NC_NOERR);
    ASSERT_EQ(nc_redef(ncid), NC_NOERR);
  });
  EXPECT_NE(fields_error(flipped).find("x starts at 1.5, not at a finite -half_width < 0"),
            std::string::npos)
      << fields_error(flipped);
  // time on (x): nc_get_var would fill 9 times into a vector of 1.
  const fs::path wrong_T = write_fields("wrong_T.nc");
  edit_netcdf(wrong_T, [](int ncid) {
    int var = -1;
    int dim_x = -1;
    ASSERT_EQ(nc_inq_varid(ncid, "time", &var), NC_NOERR);
    ASSERT_EQ(nc_rename_var(ncid, var, "time_saved"), NC_NOERR);
    ASSERT_EQ(nc_inq_dimid(ncid, "x", &dim_x), NC_NOERR);
    ASSERT_EQ(nc_def_var(ncid, "time", NC_DOUBLE, 1, &dim_x, &var), NC_NOERR);
  });
  EXPECT_NE(fields_error(wrong_T).find("variable time must have the dimensions (time)"),
            std::string::npos)
      << fields_error(wrong_T);
}

TEST(DamagedFiles, FuzzerFindingsFailCleanly) {
  // Every input a fuzz target crashed on, kept in tests/fuzz-regressions/.
  const fs::path root = source_dir() / "tests" / "fuzz-regressions";
  int files = 0;
  for (const auto& [target, read] :
       std::vector<std::pair<std::string, std::string (*)(const fs::path&)>>{
           {"checkpoint", checkpoint_error}, {"fields", fields_error}}) {
    for (const auto& entry : fs::directory_iterator(root / target)) {
      const std::string message = read(entry.path());
      EXPECT_NE(message.find(entry.path().string()), std::string::npos)
          << entry.path() << ": " << message;
      ++files;
    }
  }
  EXPECT_GE(files, 2);
}

// ---------------------------------------------------------------------------
// Untrusted files read in a child process first (io/IsolatedIo.hpp)
// ---------------------------------------------------------------------------

std::string untrusted_checkpoint_error(const fs::path& path) {
  return read_error([&] { (void)read_untrusted_checkpoint(path); });
}

std::string untrusted_fields_error(const fs::path& path) {
  return read_error([&] {
    pre_read_fields_in_child(path);
    const FieldReader reader(path);
  });
}

/// A short bound for the reads that must time out (a hang is a hang however long).
constexpr std::chrono::milliseconds kShortBound{500};

/// `message` is "<prefix>the NetCDF/HDF5 library crashed reading it (SIGSEGV):
/// the file is damaged"; AddressSanitizer (the sanitizer build) sees the bad
/// memcpy first and ends the child with exit status 1 instead.
void expect_library_crash(const std::string& message, const std::string& prefix) {
  const std::string crashed = prefix + "the NetCDF/HDF5 library crashed reading it (";
  const std::string damaged = "): the file is damaged";
  ASSERT_TRUE(message.starts_with(crashed) && message.ends_with(damaged)) << message;
  const std::string how =
      message.substr(crashed.size(), message.size() - crashed.size() - damaged.size());
  EXPECT_TRUE(how == "SIGSEGV" || how == "exit status 1") << message;
}

/// The pid a child wrote into `file`.
pid_t pid_in(const fs::path& file) {
  std::ifstream in(file);
  pid_t pid = -1;
  in >> pid;
  return pid;
}

/// Whether process `pid` is gone (reaped, not a zombie).
bool process_is_gone(pid_t pid) { return kill(pid, 0) != 0 && errno == ESRCH; }

TEST(IsolatedRead, AChildThatReadsOrFailsLeavesTheVerdictToTheCaller) {
  TempDir dir;
  const fs::path path = write_file(dir / "any.nc", "");
  ::testing::internal::CaptureStderr();
  EXPECT_NO_THROW(pre_read_in_child(path, "read", [] { std::fputs("noise\n", stderr); }));
  EXPECT_NO_THROW(pre_read_in_child(path, "read", [] { throw std::runtime_error("damaged"); }));
  EXPECT_NO_THROW(pre_read_in_child(path, "read", [] { throw 42; }));
  EXPECT_EQ(::testing::internal::GetCapturedStderr(), "");  // the child says nothing
}

TEST(IsolatedRead, AChildThatCrashesNamesTheFileAndHow) {
  TempDir dir;
  const fs::path path = write_file(dir / "any.nc", "");
  const std::string prefix = "cannot read checkpoint '" + path.string() + "': ";
  EXPECT_EQ(read_error([&] { pre_read_in_child(path, "read checkpoint", [] { std::abort(); }); }),
            prefix + "the NetCDF/HDF5 library crashed reading it (SIGABRT): the file is damaged");
  // An exit status the child never gives itself: a sanitizer's report.
  EXPECT_EQ(
      read_error([&] { pre_read_in_child(path, "read checkpoint", [] { _exit(1); }); }),
      prefix + "the NetCDF/HDF5 library crashed reading it (exit status 1): the file is damaged");
}

TEST(IsolatedRead, AChildThatDoesNotEndInTimeIsKilled) {
  TempDir dir;
  const fs::path path = write_file(dir / "any.nc", "");
  const fs::path pid_file = dir / "child.pid";
  const auto start = std::chrono::steady_clock::now();
  const std::string message = read_error([&] {
    pre_read_in_child(
        path, "read",
        [&] {
          std::ofstream(pid_file) << getpid();
          for (;;) pause();
        },
        std::chrono::seconds(2));  // long enough for the child to write its pid
  });
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(10));
  EXPECT_EQ(message, "cannot read '" + path.string() +
                         "': the NetCDF/HDF5 library did not finish reading it in 2 s (it loops "
                         "for ever on some damaged files; the read was stopped): the file is "
                         "damaged");
  EXPECT_TRUE(process_is_gone(pid_in(pid_file)));
  // The bound of the commands: 30 s, and more for a larger file.
  EXPECT_EQ(pre_read_bound(0), std::chrono::seconds(30));
  EXPECT_GT(pre_read_bound(std::uintmax_t{1} << 30), pre_read_bound(std::uintmax_t{1} << 20));
}

TEST(IsolatedRead, ASignalWhileWaitingKillsTheChildAndIsReported) {
  TempDir dir;
  const fs::path path = write_file(dir / "any.nc", "");
  const fs::path pid_file = dir / "child.pid";
  {
    const InterruptGuard interrupts;
    try {
      // The child signals its parent, as a Ctrl-C would, and then hangs.
      pre_read_in_child(path, "read", [&] {
        std::ofstream(pid_file) << getpid();
        kill(getppid(), SIGTERM);
        for (;;) pause();
      });
      FAIL() << "the pre-read ignored SIGTERM";
    } catch (const PreReadInterrupted& e) {
      EXPECT_EQ(e.signal, SIGTERM);
    }
    EXPECT_TRUE(process_is_gone(pid_in(pid_file)));
  }
  const InterruptGuard clear;  // the flag outlives a guard: no later test may see it
}

TEST(IsolatedRead, HdfCrashesAndLoopsOnDamagedFilesBecomeErrorsNamingTheFile) {
  // The size of a global-heap object of a DIMENSION_LIST set to 1.7e18: H5HG_read's memcpy.
  const fs::path checkpoint = library_crash("checkpoint-v9-hdf5-H5HG_read-segv.nc");
  expect_library_crash(untrusted_checkpoint_error(checkpoint),
                       "cannot read checkpoint '" + checkpoint.string() + "': ");
  const fs::path fields = library_crash("fields-hdf5-H5HG_read-segv.nc");
  expect_library_crash(untrusted_fields_error(fields), "cannot read '" + fields.string() + "': ");
  // The first object of the global heap zeroed: HDF5's heap parser loops for ever.
  const std::string loops =
      "': the NetCDF/HDF5 library did not finish reading it in 0.5 s (it loops for ever on some "
      "damaged files; the read was stopped): the file is damaged";
  const fs::path looping_checkpoint = library_crash("checkpoint-hdf5-H5HG-heap-loop.nc");
  EXPECT_EQ(read_error([&] {
              pre_read_in_child(
                  looping_checkpoint, "read checkpoint",
                  [&] { (void)read_checkpoint(looping_checkpoint); }, kShortBound);
            }),
            "cannot read checkpoint '" + looping_checkpoint.string() + loops);
  const fs::path looping_fields = library_crash("fields-hdf5-H5HG-heap-loop.nc");
  EXPECT_EQ(read_error([&] {
              pre_read_in_child(
                  looping_fields, "read", [&] { const FieldReader reader(looping_fields); },
                  kShortBound);
            }),
            "cannot read '" + looping_fields.string() + loops);
}

TEST(IsolatedRead, OrdinaryDamageGivesTheReadersOwnMessage) {
  TempDir dir;
  const fs::path root = source_dir();
  std::vector<fs::path> checkpoints = {dir / "missing.nc", dir.path(),
                                       library_crash("checkpoint-hdf5-H5HG_read-segv.nc")};
  std::vector<fs::path> fields = {dir / "missing.nc", dir.path()};
  for (const auto& entry :
       fs::directory_iterator(root / "tests" / "fuzz-regressions" / "checkpoint"))
    checkpoints.push_back(entry.path());
  for (const auto& entry : fs::directory_iterator(root / "tests" / "fuzz-corpus" / "checkpoint"))
    checkpoints.push_back(entry.path());
  for (const auto& entry : fs::directory_iterator(root / "tests" / "fuzz-regressions" / "fields"))
    fields.push_back(entry.path());
  for (const auto& entry : fs::directory_iterator(root / "tests" / "fuzz-corpus" / "fields"))
    fields.push_back(entry.path());
  const fs::path damaged = dir / "checkpoint.nc";
  write_checkpoint(damaged, plausible_state(small_case_parameters()), small_case_parameters());
  ehlsim::testing::rewrite_attribute(damaged, "T", std::numeric_limits<double>::quiet_NaN());
  checkpoints.push_back(damaged);
  int damaged_files = 0;
  for (const fs::path& path : checkpoints) {
    const std::string expected = checkpoint_error(path);
    damaged_files += expected.empty() ? 0 : 1;
    EXPECT_EQ(untrusted_checkpoint_error(path), expected) << path;
  }
  for (const fs::path& path : fields) {
    const std::string expected = fields_error(path);
    damaged_files += expected.empty() ? 0 : 1;
    EXPECT_EQ(untrusted_fields_error(path), expected) << path;
  }
  EXPECT_GE(damaged_files, 14);
}

// ---------------------------------------------------------------------------
// Files written in a child process (io/IsolatedIo.hpp)
// ---------------------------------------------------------------------------

TEST(IsolatedWrite, AWriteThatFailsGivesItsOwnMessage) {
  TempDir dir;
  const fs::path path = dir / "out.nc.part";
  EXPECT_NO_THROW(write_in_child(path, "write", [&] { write_file(path, "done"); }));
  EXPECT_EQ(read_file(path), "done");  // the child's file is the caller's
  EXPECT_EQ(read_error([&] {
              write_in_child(path, "write", [] {
                throw std::runtime_error("cannot write 'out': nc_close: disk on fire");
              });
            }),
            "cannot write 'out': nc_close: disk on fire");
  EXPECT_EQ(read_error([&] { write_in_child(path, "write", [] { throw 42; }); }),
            "an exception that is not a std::exception");
  // A message longer than a pipe's buffer comes back whole.
  const std::string long_message(200'000, 'x');
  EXPECT_EQ(read_error([&] {
              write_in_child(path, "write", [&] { throw std::runtime_error(long_message); });
            }),
            long_message);
}

TEST(IsolatedWrite, ACrashWhileWritingBecomesAnErrorNamingTheFile) {
  TempDir dir;
  const fs::path path = dir / "checkpoint.nc.part";
  EXPECT_EQ(read_error([&] { write_in_child(path, "write checkpoint", [] { std::abort(); }); }),
            "cannot write checkpoint '" + path.string() +
                "': the NetCDF/HDF5 library crashed writing it (SIGABRT; HDF5 1.10.8 does when "
                "the last write of a file fails, e.g. on an I/O error of the disk)");
}

TEST(IsolatedWrite, WithSigchldIgnoredTheChildsReportDecides) {
  // A process started with SIGCHLD ignored (inherited through exec) cannot
  // wait for its children: the kernel reaps them.  A crash must not pass for
  // a write that returned.
  struct sigaction ignore {};
  ignore.sa_handler = SIG_IGN;
  sigemptyset(&ignore.sa_mask);
  struct sigaction previous {};
  ASSERT_EQ(sigaction(SIGCHLD, &ignore, &previous), 0);
  TempDir dir;
  const fs::path path = dir / "checkpoint.nc.part";
  const std::string crashed =
      read_error([&] { write_in_child(path, "write", [] { std::abort(); }); });
  const std::string threw = read_error(
      [&] { write_in_child(path, "write", [] { throw std::runtime_error("disk on fire"); }); });
  const std::string returned = read_error([&] { write_in_child(path, "write", [] {}); });
  sigaction(SIGCHLD, &previous, nullptr);
  EXPECT_EQ(crashed, "cannot write '" + path.string() +
                         "': the NetCDF/HDF5 library crashed writing it (ended without a report; "
                         "HDF5 1.10.8 does when the last write of a file fails, e.g. on an I/O "
                         "error of the disk)");
  EXPECT_EQ(threw, "disk on fire");
  EXPECT_EQ(returned, "");
}

TEST(IsolatedWrite, ASignalDoesNotStopAWrite) {
  TempDir dir;
  const fs::path path = dir / "checkpoint.nc.part";
  {
    const InterruptGuard interrupts;
    // The child signals its parent, as a Ctrl-C would, and then writes: the
    // checkpoint written after a SIGINT must be complete.
    write_in_child(path, "write checkpoint", [&] {
      kill(getppid(), SIGINT);
      std::this_thread::sleep_for(std::chrono::milliseconds(300));
      write_file(path, "complete");
    });
    EXPECT_EQ(InterruptGuard::received(), SIGINT);
    EXPECT_EQ(read_file(path), "complete");
  }
  const InterruptGuard clear;  // the flag outlives a guard: no later test may see it
}

// ---------------------------------------------------------------------------
// Progress line
// ---------------------------------------------------------------------------

TEST(Progress, EndTimeEstimate) {
  const double inf = std::numeric_limits<double>::infinity();
  const double margin = kLiftOffMargin * kDryContactDuration;
  EXPECT_EQ(estimate_end_time(0.5, 0.5, -1.0, 3.0, 1.0, 1.0), 3.0);  // finite T_end
  // Before the rebound: dry contact from Delta0/V0, plus its duration and the margin.
  EXPECT_DOUBLE_EQ(estimate_end_time(0.5, 0.5, -1.0, inf, 1.0, 1.0),
                   1.0 + kDryContactDuration + margin);
  // A slower ball stays longer in contact: 3.2181 V0^(-1/5) (model.md).
  const double slow_duration = kDryContactDuration * std::pow(0.5, -0.2);
  EXPECT_DOUBLE_EQ(estimate_end_time(0.5, 1.5, -0.5, inf, 2.0, 0.5),
                   4.0 + (1.0 + kLiftOffMargin) * slow_duration);
  // Rebound: Delta extrapolated back to 0.
  EXPECT_DOUBLE_EQ(estimate_end_time(3.6, -0.5, 0.9, inf, 1.0, 1.0), 3.6 + 0.5 / 0.9 + margin);
  // Late: never earlier than T + margin.
  EXPECT_DOUBLE_EQ(estimate_end_time(6.0, 0.1, -0.01, inf, 1.0, 1.0), 6.0 + margin);
}

TEST(Progress, DurationsAndText) {
  EXPECT_EQ(format_duration(12.34), "12.3s");
  EXPECT_EQ(format_duration(245.0), "4m05s");
  EXPECT_EQ(format_duration(7380.0), "2h03m");
  EXPECT_EQ(format_duration(-1.0), "?");
  const ProgressLine line(false, std::numeric_limits<double>::infinity(), 1.0, 1.0);
  const std::string text = line.text(record(223, 2.0), 10.0);
  EXPECT_NE(text.find("T 2.0000/~"), std::string::npos) << text;
  EXPECT_NE(text.find("step 223"), std::string::npos) << text;
  EXPECT_NE(text.find("cycles 225"), std::string::npos) << text;
  EXPECT_NE(text.find("left"), std::string::npos) << text;
  EXPECT_NE(line.text(record(223, 2.0), 10.0, true).find("done in 10.0s"), std::string::npos);
}

/// What a status line wrote into the temporary file `stream` (up to 4 KiB).
std::string text_written_to(std::FILE* stream) {
  std::rewind(stream);
  std::string text(4096, '\0');
  text.resize(std::fread(text.data(), 1, text.size(), stream));
  return text;
}

TEST(Progress, QuietPrintsNothingAndLogsPrintLines) {
  std::FILE* quiet_stream = std::tmpfile();
  std::FILE* log_stream = std::tmpfile();
  ASSERT_TRUE(quiet_stream && log_stream);
  {
    ProgressLine quiet(false, 1.0, 1.0, 1.0, quiet_stream);
    ProgressLine log(true, 1.0, 1.0, 1.0, log_stream);  // a file: full lines, throttled
    for (int step = 1; step <= 100; ++step) {
      quiet.update(record(step, 0.01 * step));
      log.update(record(step, 0.01 * step));
    }
    quiet.finish();
    log.finish();
  }
  EXPECT_EQ(std::ftell(quiet_stream), 0L);
  const std::string text = text_written_to(log_stream);
  // The first step, then (within the 10 s throttle) only the final state.
  EXPECT_EQ(std::count(text.begin(), text.end(), '\n'), 2) << text;
  EXPECT_NE(text.find("step 1 "), std::string::npos) << text;
  EXPECT_NE(text.find("step 100 "), std::string::npos) << text;
  EXPECT_EQ(text.find('\r'), std::string::npos);
  std::fclose(quiet_stream);
  std::fclose(log_stream);
}

TEST(Progress, AStatusLineShowsANoteAndThenItsStateAgain) {
  std::FILE* log_stream = std::tmpfile();
  ASSERT_TRUE(log_stream);
  {
    StatusLine line(true, log_stream);  // a file: full lines, throttled
    const auto state = [](int n) {
      return [n](double, bool done) { return fmt::format("state {}{}", n, done ? " done" : ""); };
    };
    for (int n = 1; n <= 50; ++n) line.update(state(n));
    line.note("an event");
    for (int n = 51; n <= 100; ++n) line.update(state(n));
    line.finish();
  }
  const std::string text = text_written_to(log_stream);
  // The first state, the note, the first state after it, the last one done.
  EXPECT_EQ(text, "state 1\nan event\nstate 51\nstate 100 done\n");
  std::fclose(log_stream);
}

TEST(Progress, ALogEndsWithTheDoneLineAlsoWhenTheLastStateWasPrinted) {
  // A rolling run whose 10-second line fell on its last cycle ended its log
  // without "done in".
  std::FILE* log_stream = std::tmpfile();
  ASSERT_TRUE(log_stream);
  {
    StatusLine line(true, log_stream);
    line.update([](double, bool done) { return std::string(done ? "state done" : "state"); });
    line.finish();
  }
  const std::string text = text_written_to(log_stream);
  EXPECT_EQ(text, "state\nstate done\n");
  std::fclose(log_stream);
}

// ---------------------------------------------------------------------------
// RunOutput
// ---------------------------------------------------------------------------

TEST(RunOutput, WritesAllFilesOnFinish) {
  TempDir dir;
  const fs::path run = dir / "nested" / "run";
  const ImpactConfig config = load_config(
      std::nullopt, {"grid.points=9", "solver.coarsest_points=5", "output.snapshot_every=3",
                     "output.snapshot_times=[0.45, 0.0, 2.0]", "time.dT=0.1"});
  const Grid2D grid(9, 1.5);
  {
    RunOutput output(run, config, false, {{"config_file", nullptr}});
    output.on_start(grid);
    for (int step = 1; step <= 10; ++step) {
      // The solver flags every third step; 0.45 adds step 5 (T = 0.5), 0.0 adds step 1.
      for (int cycle = 0; cycle <= 2; ++cycle)
        output.on_cycle({step, 0.1 * step, 0.1, 0, 1.0, cycle, std::pow(0.1, cycle + 3)});
      output.on_step(record(step, 0.1 * step), Field(grid, step), Field(grid, 1.0), step % 3 == 0);
    }
    EXPECT_EQ(files_in(run), (std::vector<std::string>{"convergence.csv.part", "fields.nc.part",
                                                       "timeseries.csv.part"}));
    RunSummary summary;
    summary.steps = 10;
    summary.lifted_off = true;
    summary.T_final = 1.0;
    summary.T_lift_off = 0.95;
    summary.rebound_speed = 0.9;
    summary.max_force = 2.5;
    summary.min_h_center = 0.01;
    summary.impulse = 1.9;
    output.on_finish(summary);
    EXPECT_TRUE(output.committed());
    EXPECT_EQ(output.snapshots_written(), 5u);  // steps 1, 3, 5, 6, 9
  }
  EXPECT_EQ(files_in(run), (std::vector<std::string>{"convergence.csv", "fields.nc", "run.json",
                                                     "timeseries.csv"}));
  const nlohmann::json j = nlohmann::json::parse(read_file(run / "run.json"));
  EXPECT_EQ(j["program"]["version"], EHLSIM_VERSION);
  EXPECT_EQ(j["parameters"], effective_parameters_json(config));
  EXPECT_EQ(j["derived"]["M"].get<double>(), config.M);
  EXPECT_EQ(j["grid"]["points"], 9);
  EXPECT_DOUBLE_EQ(j["grid"]["h"].get<double>(), 0.375);
  EXPECT_DOUBLE_EQ(j["dT"].get<double>(), 0.1);
  EXPECT_EQ(j["results"]["steps"], 10);
  EXPECT_EQ(j["results"]["T_lift_off"].get<double>(), 0.95);
  EXPECT_EQ(j["results"]["rebound_speed"].get<double>(), 0.9);
  EXPECT_EQ(j["results"]["max_force"].get<double>(), 2.5);
  EXPECT_EQ(j["results"]["impulse"].get<double>(), 1.9);
  EXPECT_EQ(j["files"]["snapshots"], 5);
  EXPECT_TRUE(j["invocation"]["config_file"].is_null());
  EXPECT_GE(j["wall_seconds"].get<double>(), 0.0);

  int ncid = -1;
  ASSERT_EQ(nc_open((run / "fields.nc").c_str(), NC_NOWRITE, &ncid), NC_NOERR);
  int var = -1;
  ASSERT_EQ(nc_inq_varid(ncid, "time", &var), NC_NOERR);
  std::vector<double> T(5);
  nc_get_var_double(ncid, var, T.data());
  EXPECT_EQ(T, (std::vector<double>{0.1, 0.30000000000000004, 0.5, 0.6000000000000001, 0.9}));
  nc_close(ncid);

  const std::string csv = read_file(run / "timeseries.csv");
  EXPECT_EQ(std::count(csv.begin(), csv.end(), '\n'), 11);
  // One row per cycle report, with the header of RunOutput::kConvergenceHeader.
  const std::string cycles = read_file(run / "convergence.csv");
  EXPECT_EQ(std::count(cycles.begin(), cycles.end(), '\n'), 31);
  EXPECT_EQ(cycles.substr(0, cycles.find('\n')), RunOutput::kConvergenceHeader);
  EXPECT_NE(cycles.find("\n10,1,0.1,0,1,2,1e-05\n"), std::string::npos);
  EXPECT_EQ(j["files"]["convergence_rows"], 30);
}

TEST(RunOutput, SnapshotStartDelaysThePeriodicSnapshotsOnly) {
  TempDir dir;
  const ImpactConfig config = load_config(
      std::nullopt, {"grid.points=9", "solver.coarsest_points=5", "output.snapshot_every=2",
                     "output.snapshot_start=0.55", "output.snapshot_times=[0.3]", "time.dT=0.1"});
  const Grid2D grid(9, 1.5);
  RunOutput output(dir.path(), config, false);
  output.add_file("spike", "spike.csv");
  output.on_start(grid);
  for (int step = 1; step <= 9; ++step) {
    StepRecord r = record(step, 0.1 * step);
    if (step == 9) r.p_max = 0.0;  // lift-off: no pressure left; the solver flags the last step
    output.on_step(r, Field(grid), Field(grid), step % 2 == 0 || step == 9);
  }
  output.on_finish(RunSummary{});
  // Step 3 (snapshot_times), steps 6 and 8 (periodic from T = 0.55), step 9 (the last);
  // not the periodic steps 2 and 4.
  EXPECT_EQ(output.snapshots_written(), 4u);
  const nlohmann::json j = nlohmann::json::parse(read_file(dir / "run.json"));
  EXPECT_EQ(j["files"]["spike"], "spike.csv");
  EXPECT_EQ(j["parameters"]["output"]["snapshot_start"].get<double>(), 0.55);
}

/// The pressure of step `step` of the spike tests: a ring of pressure moving
/// inward on a dome.
Field moving_ring(const Grid2D& grid, int step) {
  const double R0 = 0.8 - 0.5 * spike_time(step);
  Field P(grid);
  for (int j = 0; j < grid.n; ++j) {
    for (int i = 0; i < grid.n; ++i) {
      const double R = std::hypot(grid.x(i), grid.y(j));
      P(i, j) = std::max(0.0, 1.0 - R * R) + 0.5 * std::exp(-std::pow((R - R0) / 0.06, 2));
    }
  }
  return P;
}

// spike.csv is written with a lag of one step (V_s needs the next step): its
// V_s column must be what the batch finite differences give for its R_s column.
TEST(SpikeOutput, OneRowPerStepWithTheFiniteDifferenceSpeed) {
  TempDir dir;
  const ImpactConfig config =
      load_config(std::nullopt, {"grid.points=65", "solver.coarsest_points=5"});
  const Grid2D grid(65, 1.5);
  const int steps = 7;
  {
    SpikeOutput spike(dir.path(), config);
    spike.on_start(grid);
    for (int step = 1; step <= steps; ++step)
      spike.on_step(record(step, spike_time(step)), moving_ring(grid, step), Field(grid), false);
    EXPECT_EQ(files_in(dir.path()), std::vector<std::string>{"spike.csv.part"});
    spike.on_finish(RunSummary{});
  }
  EXPECT_EQ(files_in(dir.path()), std::vector<std::string>{"spike.csv"});
  std::istringstream csv(read_file(dir / "spike.csv"));
  std::string line;
  std::getline(csv, line);
  EXPECT_EQ(line, SpikeSeriesWriter::kHeader);
  std::vector<double> T, R, V;
  while (std::getline(csv, line)) {
    double t = 0, r = 0, p = 0, v = 0;
    ASSERT_EQ(std::sscanf(line.c_str(), "%lf,%lf,%lf,%lf", &t, &r, &p, &v), 4) << line;
    T.push_back(t);
    R.push_back(r);
    V.push_back(v);
  }
  ASSERT_EQ(T.size(), static_cast<std::size_t>(steps));
  const std::vector<double> expected = finite_difference_rate(T, R);
  for (std::size_t k = 0; k < V.size(); ++k) {
    EXPECT_NEAR(V[k], expected[k], 1e-6 * std::abs(expected[k])) << k;  // 10 digits in the file
    EXPECT_LT(V[k], 0.0) << k;                                          // inward
  }
}

// A restart after step k (SpikeOutput::resume_after with the checkpoint's
// pressure) writes the rows of the uninterrupted run after k, V_s included:
// three-point differences from its first row on.
TEST(SpikeOutput, ARestartWritesTheRowsOfTheUninterruptedRun) {
  TempDir dir;
  const ImpactConfig config =
      load_config(std::nullopt, {"grid.points=65", "solver.coarsest_points=5"});
  const Grid2D grid(65, 1.5);
  constexpr int kSteps = 7;
  constexpr int kCheckpointStep = 3;
  const auto write = [&](const fs::path& run, bool restart) {
    SpikeOutput spike(run, config);
    spike.on_start(grid);
    if (restart)
      spike.resume_after(spike_time(kCheckpointStep), moving_ring(grid, kCheckpointStep));
    for (int step = restart ? kCheckpointStep + 1 : 1; step <= kSteps; ++step)
      spike.on_step(record(step, spike_time(step)), moving_ring(grid, step), Field(grid), false);
    spike.on_finish(RunSummary{});
    std::vector<std::string> rows;
    std::istringstream csv(read_file(run / SpikeOutput::kFile));
    for (std::string line; std::getline(csv, line);) rows.push_back(line);
    return rows;
  };
  const std::vector<std::string> full = write(dir / "full", false);
  const std::vector<std::string> restarted = write(dir / "restarted", true);
  ASSERT_EQ(full.size(), kSteps + 1u);
  // The header, then the rows after the checkpoint's step.
  std::vector<std::string> expected{full.front()};
  expected.insert(expected.end(), full.begin() + 1 + kCheckpointStep, full.end());
  EXPECT_EQ(restarted, expected);
}

TEST(RunOutput, ARestartDoesNotStoreReachedSnapshotTimesAgain) {
  TempDir dir;
  const ImpactConfig config = load_config(
      std::nullopt, {"grid.points=9", "solver.coarsest_points=5", "output.snapshot_every=100",
                     "output.snapshot_times=[0.25, 0.7]", "time.dT=0.1"});
  const Grid2D grid(9, 1.5);
  RunOutput output(dir.path(), config, false);
  output.on_start(grid);
  // The checkpoint of step 5 (T = 0.5): the run before it stored T = 0.25 at step 3.
  output.resume_after(0.5);
  for (int step = 6; step <= 8; ++step)
    output.on_step(record(step, 0.1 * step), Field(grid), Field(grid), false);
  EXPECT_EQ(output.snapshots_written(), 1u);  // T = 0.7 only, at step 7
}

TEST(RunOutput, FailedRunLeavesNoFiles) {
  TempDir dir;
  const ImpactConfig config =
      load_config(std::nullopt, {"grid.points=9", "solver.coarsest_points=5"});
  const Grid2D grid(9, 1.5);
  {
    RunOutput output(dir.path(), config, false);
    output.on_start(grid);
    output.on_step(record(1, 0.1), Field(grid), Field(grid), true);
    // the solver throws: on_finish is never called
  }
  EXPECT_TRUE(files_in(dir.path()).empty());
}

TEST(RunOutput, RunJsonHasNullForMissingLiftOff) {
  TempDir dir;
  const ImpactConfig config =
      load_config(std::nullopt, {"grid.points=9", "solver.coarsest_points=5"});
  RunOutput output(dir.path(), config, false);
  RunSummary summary;
  summary.T_lift_off = std::numeric_limits<double>::quiet_NaN();
  summary.rebound_speed = std::numeric_limits<double>::quiet_NaN();
  const nlohmann::json j = output.run_json(summary);
  EXPECT_TRUE(j["results"]["T_lift_off"].is_null());
  EXPECT_TRUE(j["results"]["rebound_speed"].is_null());
}

// ------------------------------------------------- run directory, lock, signals

/// The names in `dir`.
std::set<std::string> names_in(const fs::path& dir) {
  std::set<std::string> names;
  for (const auto& entry : fs::directory_iterator(dir)) names.insert(entry.path().filename());
  return names;
}

/// Writes a minimal earlier ehlsim run into `dir`.
void write_earlier_run(const fs::path& dir) {
  fs::create_directories(dir);
  write_file(dir / "run.json", R"({"program": {"name": "ehlsim"}})");
  write_file(dir / "timeseries.csv", "old\n");
  write_file(dir / "checkpoint.nc", "old checkpoint\n");
}

TEST(RunDirectory, PublishesIntoAMissingDirectory) {
  TempDir dir;
  const fs::path target = dir / "run";
  {
    RunDirectory run(target);
    EXPECT_EQ(run.staging().parent_path(), fs::canonical(dir.path()));
    EXPECT_TRUE(run.staging().filename().string().starts_with(".run.part-"));
    EXPECT_EQ(run.checkpoint(), dir / "run.checkpoint.nc");
    write_file(run.staging() / "run.json", "new\n");
    EXPECT_FALSE(fs::exists(target));  // nothing visible before publish
    run.publish();
  }
  EXPECT_EQ(read_file(target / "run.json"), "new\n");
  EXPECT_EQ(names_in(dir.path()), std::set<std::string>{"run"});  // no staging, no lock
}

TEST(RunDirectory, ReplacesAnEarlierRunAsAWhole) {
  TempDir dir;
  const fs::path target = dir / "run";
  write_earlier_run(target);
  {
    RunDirectory run(target);
    write_file(run.checkpoint(), "checkpoint of the new run\n");
    run.stage_checkpoint();
    // Another file put there (renamed over it) is not published.
    write_file(dir / "other.nc", "another file\n");
    fs::rename(dir / "other.nc", run.checkpoint());
    write_file(run.staging() / "run.json", "new\n");
    EXPECT_EQ(read_file(target / "timeseries.csv"), "old\n");  // the earlier run until publish
    run.publish();
  }
  // The earlier run's files are gone (no stale timeseries.csv); the checkpoint
  // of the new run moved in.
  EXPECT_EQ(names_in(target), (std::set<std::string>{"checkpoint.nc", "run.json"}));
  EXPECT_EQ(read_file(target / "checkpoint.nc"), "checkpoint of the new run\n");
  EXPECT_EQ(names_in(dir.path()), (std::set<std::string>{"run", "run.checkpoint.nc"}));
  EXPECT_EQ(read_file(dir / "run.checkpoint.nc"), "another file\n");  // not the run's: it stays
}

TEST(RunDirectory, AnUnpublishedRunLeavesTheEarlierOneAndItsCheckpoint) {
  TempDir dir;
  const fs::path target = dir / "run";
  write_earlier_run(target);
  {
    RunDirectory run(target);
    write_file(run.staging() / "timeseries.csv", "new\n");
    write_file(run.checkpoint(), "kept\n");
  }  // failed: never published
  EXPECT_EQ(read_file(target / "timeseries.csv"), "old\n");
  EXPECT_EQ(read_file(target / "checkpoint.nc"), "old checkpoint\n");
  EXPECT_EQ(read_file(dir / "run.checkpoint.nc"), "kept\n");
  EXPECT_EQ(names_in(dir.path()), (std::set<std::string>{"run", "run.checkpoint.nc"}));
}

TEST(RunDirectory, RefusesACheckpointBesideItThatIsNotEhlsims) {
  TempDir dir;
  const fs::path target = dir / "run";
  const auto message = [&] {
    try {
      const RunDirectory run(target);
      run.refuse_foreign_checkpoint();
    } catch (const ConfigError& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  const std::string start =
      "--out '" + target.string() + "': a run keeps its checkpoint beside it, and ";
  const fs::path checkpoint = dir / "run.checkpoint.nc", partial = dir / "run.checkpoint.nc.part";
  EXPECT_EQ(message(), "accepted");
  write_file(partial, "");  // a run killed as it began one
  EXPECT_EQ(message(), "accepted");
  int ncid = -1;  // an earlier run's (any NetCDF-4 file: the run reads it only to resume)
  ASSERT_EQ(nc_create(checkpoint.c_str(), NC_CLOBBER | NC_NETCDF4, &ncid), NC_NOERR);
  ASSERT_EQ(nc_close(ncid), NC_NOERR);
  EXPECT_EQ(message(), "accepted");
  write_file(partial, "the user's notes");
  EXPECT_NE(
      message().find(start + "cannot replace '" + partial.string() + "': not a NetCDF-4 file"),
      std::string::npos)
      << message();
  fs::remove(partial);
  fs::remove(checkpoint);
  fs::create_symlink(dir / "nowhere", checkpoint);  // a dangling link was replaced, then deleted
  EXPECT_EQ(message(), start + "'" + checkpoint.string() +
                           "' is a symbolic link: move it, or choose another --out");
  EXPECT_TRUE(fs::is_symlink(checkpoint));
}

/// Builds below `dir` a chain of directories whose full path is longer than
/// PATH_MAX, with a file at its end (made relative to descriptors, as the
/// paths themselves are too long for the system calls).
void make_tree_deeper_than_path_max(const fs::path& dir) {
  const std::string name(200, 'd');
  int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  ASSERT_GE(fd, 0);
  for (std::size_t length = 0; length <= PATH_MAX; length += name.size() + 1) {
    ASSERT_EQ(::mkdirat(fd, name.c_str(), 0755), 0);
    const int child = ::openat(fd, name.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    ::close(fd);
    ASSERT_GE(child, 0);
    fd = child;
  }
  const int file = ::openat(fd, "debris", O_WRONLY | O_CREAT | O_CLOEXEC, 0644);
  EXPECT_GE(file, 0);
  ::close(file);
  ::close(fd);
}

TEST(RunDirectory, RemovesTheDebrisOfAKilledRun) {
  TempDir dir;
  fs::create_directories(dir / ".run.part-999999");
  write_file(dir / ".run.part-999999" / "fields.nc.part", "debris");
  // Removed by paths, a tree deeper than PATH_MAX stayed ("File name too long").
  make_tree_deeper_than_path_max(dir / ".run.part-999999");
  fs::create_directories(dir / ".run.old-999999");
  fs::create_directories(dir / ".other.part-999999");  // another target's: not ours
  // Not a killed run's: no process id, or a live process's (init's).
  const std::set<std::string> users = {".other.part-999999", ".run.part-mydata", ".run.part-",
                                       ".run.part-1", ".run.old-1x"};
  for (const std::string& name : users) write_file(dir / name, "the user's");
  {
    RunDirectory run(dir / "run");
    std::set<std::string> expected = users;
    expected.insert({".run.lock", run.staging().filename().string()});
    EXPECT_EQ(names_in(dir.path()), expected);
  }
  EXPECT_EQ(names_in(dir.path()), users);
}

TEST(RunDirectory, TellsItsStagingDirectoryByName) {
  TempDir dir;
  {
    RunDirectory run(dir / "run");
    EXPECT_EQ(run_directory_staged_in(run.staging()), dir / "run");
  }
  EXPECT_EQ(run_directory_staged_in(dir / ".a.b.part-999999/"), dir / "a.b");
  EXPECT_EQ(run_directory_staged_in(dir / "..hidden.part-1"), dir / ".hidden");
  // Through a link, and as "." from within (symbolic links resolved).
  fs::create_directories(dir / ".run.part-12");
  fs::create_directory_symlink(".run.part-12", dir / "link");
  EXPECT_EQ(run_directory_staged_in(dir / "link"), dir / "run");
  EXPECT_EQ(run_directory_staged_in(dir / ".run.part-12" / "."), dir / "run");
  // No process id, no NAME, no leading dot: not a staging directory's name.
  for (const char* name : {"run", ".run.part-", ".run.part-notes", ".run.part-1x", "..part-1",
                           "run.part-1", ".run.part-12345678", ".run.old-1"})
    EXPECT_EQ(run_directory_staged_in(dir / name), std::nullopt) << name;
}

TEST(RunDirectory, RefusesWhatEhlsimDidNotWrite) {
  TempDir dir;
  const auto message = [](const fs::path& target) {
    try {
      RunDirectory run(target);
    } catch (const ConfigError& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  const std::string policy =
      ": ehlsim writes only into a new or empty directory or over an earlier ehlsim run; choose "
      "another --out, or move the files yourself";
  fs::create_directories(dir / "empty");
  EXPECT_EQ(message(dir / "empty"), "accepted");
  fs::create_directories(dir / "user");
  write_file(dir / "user" / "data.csv", "x");
  EXPECT_EQ(message(dir / "user"), "--out '" + (dir / "user").string() +
                                       "' is not empty and holds no ehlsim run.json" + policy);
  write_earlier_run(dir / "run");
  fs::create_directories(dir / "run" / "gauss");
  write_file(dir / "run" / "gauss" / "spike_profiles.csv", "x");  // ehlsim spike --out run/gauss
  EXPECT_EQ(message(dir / "run"), "accepted");
  write_file(dir / "run" / ".gauss.lock", "pid 1");  // left by a killed spike --out run/gauss
  EXPECT_EQ(message(dir / "run"), "accepted");
  {
    // ... and held by one that runs: replacing run would pull its directory away.
    const PathLock busy(resolve_run_directory(dir / "run" / "gauss"), dir / "run" / "gauss");
    EXPECT_EQ(message(dir / "run"), "--out '" + (dir / "run").string() + "' holds '" +
                                        (dir / "run" / ".gauss.lock").string() +
                                        "', the lock of an ehlsim run that writes there now: "
                                        "wait for it to end, or choose another --out");
  }
  write_file(dir / "run" / ".gauss.lock", "pid 1");  // the lock's file goes with its holder
  EXPECT_EQ(message(dir / "run"), "accepted");
  write_file(dir / "run" / ".notes.lock", "my notes");  // a lock's name, the user's text
  EXPECT_EQ(message(dir / "run"), "--out '" + (dir / "run").string() + "' holds '" +
                                      (dir / "run" / ".notes.lock").string() +
                                      "', which ehlsim did not write" + policy);
  fs::remove(dir / "run" / ".notes.lock");
  write_file(dir / "run" / "rolling.png", "x");  // scripts/plot_rolling.py's figure
  EXPECT_EQ(message(dir / "run"), "accepted");
  write_file(dir / "run" / "gauss" / "plot.png", "x");
  EXPECT_EQ(message(dir / "run"), "--out '" + (dir / "run").string() + "' holds '" +
                                      (dir / "run" / "gauss" / "plot.png").string() +
                                      "', which ehlsim did not write" + policy);
  fs::remove(dir / "run" / "gauss" / "plot.png");
  fs::create_directories(dir / "run" / "mine" / "empty");  // the user's: a run makes none
  EXPECT_EQ(message(dir / "run"), "--out '" + (dir / "run").string() + "' holds '" +
                                      (dir / "run" / "mine" / "empty").string() +
                                      "', which ehlsim did not write" + policy);
  write_file(dir / "afile", "x");
  EXPECT_EQ(message(dir / "afile"),
            "--out '" + (dir / "afile").string() + "' exists and is not a directory");
  EXPECT_EQ(message(""), "--out '': the run directory needs a name");
  EXPECT_EQ(names_in(dir / "user"), std::set<std::string>{"data.csv"});  // untouched
}

TEST(RunDirectory, ARunIntoASymbolicLinkReplacesTheDirectoryItPointsTo) {
  TempDir dir;
  const fs::path real = dir / "real";
  write_earlier_run(real);
  fs::create_directory_symlink("real", dir / "link");
  {
    RunDirectory run(dir / "link");
    EXPECT_EQ(run.target(), dir / "link");                    // messages name DIR as given
    EXPECT_EQ(run.checkpoint(), dir / "real.checkpoint.nc");  // beside the data, not the link
    write_file(run.staging() / "run.json", "new\n");
    run.publish();
  }
  EXPECT_TRUE(fs::is_symlink(dir / "link"));
  EXPECT_EQ(names_in(real), std::set<std::string>{"run.json"});
  EXPECT_EQ(read_file(real / "run.json"), "new\n");
  EXPECT_EQ(names_in(dir.path()), (std::set<std::string>{"link", "real"}));

  // A dangling link (a chain, here) gets its target created, as a shell's `>` would.
  fs::create_directory_symlink("sub/later", dir / "next");
  fs::create_directory_symlink("next", dir / "chain");
  {
    RunDirectory run(dir / "chain");
    write_file(run.staging() / "run.json", "later\n");
    run.publish();
  }
  EXPECT_TRUE(fs::is_symlink(dir / "chain"));
  EXPECT_TRUE(fs::is_symlink(dir / "next"));
  EXPECT_EQ(read_file(dir / "sub" / "later" / "run.json"), "later\n");

  // A loop is bad input, named.
  fs::create_directory_symlink("loop-b", dir / "loop-a");
  fs::create_directory_symlink("loop-a", dir / "loop-b");
  try {
    RunDirectory run(dir / "loop-a");
    FAIL() << "a symbolic link loop was accepted";
  } catch (const ConfigError& e) {
    EXPECT_EQ(std::string(e.what()), "--out '" + (dir / "loop-a").string() +
                                         "': too many levels of symbolic links (a loop?)");
  }
  // So is a loop in a parent of --out, which the run's parents cannot be made in.
  const fs::path below_loop = dir / "loop-a" / "run";
  try {
    RunDirectory run(below_loop);
    FAIL() << "a run below a symbolic link loop was accepted";
  } catch (const ConfigError& e) {
    EXPECT_EQ(std::string(e.what()),
              "--out '" + below_loop.string() + "': too many levels of symbolic links (a loop?)");
  }
}

/// The inode of `path` (a hard link shares it).
ino_t inode_of(const fs::path& path) {
  struct stat status {};
  EXPECT_EQ(lstat(path.c_str(), &status), 0) << path;
  return status.st_ino;
}

TEST(RunDirectory, AnAmendmentReplacesItsFilesAndKeepsEverythingElse) {
  TempDir dir;
  const fs::path target = dir / "run";
  write_earlier_run(target);
  write_file(target / "spike_profiles.csv", "old spike\n");
  write_file(target / "notes.txt", "mine\n");  // not ehlsim's: carried, not refused
  fs::create_directories(target / "gauss");
  write_file(target / "gauss" / "spike_profiles.csv", "gauss\n");
  const ino_t timeseries = inode_of(target / "timeseries.csv");
  write_file(dir / "run.checkpoint.nc", "an interrupted run's\n");
  {
    RunDirectory run(target, RunDirectory::Amend{{"spike_profiles.csv", "axis_profiles.csv"}});
    write_file(run.staging() / "spike_profiles.csv", "new spike\n");
    write_file(run.staging() / "axis_profiles.csv", "new axis\n");
    write_file(target / "late.txt", "came during the analysis\n");
    EXPECT_EQ(read_file(target / "spike_profiles.csv"), "old spike\n");  // until publish
    run.publish();
  }
  EXPECT_EQ(names_in(target), (std::set<std::string>{"axis_profiles.csv", "checkpoint.nc", "gauss",
                                                     "late.txt", "notes.txt", "run.json",
                                                     "spike_profiles.csv", "timeseries.csv"}));
  EXPECT_EQ(read_file(target / "spike_profiles.csv"), "new spike\n");
  EXPECT_EQ(read_file(target / "axis_profiles.csv"), "new axis\n");
  EXPECT_EQ(read_file(target / "notes.txt"), "mine\n");
  EXPECT_EQ(read_file(target / "late.txt"), "came during the analysis\n");
  EXPECT_EQ(read_file(target / "gauss" / "spike_profiles.csv"), "gauss\n");
  EXPECT_EQ(inode_of(target / "timeseries.csv"), timeseries);  // linked, not copied
  // The checkpoint of an interrupted impact run into DIR is not the amendment's to remove.
  EXPECT_EQ(names_in(dir.path()), (std::set<std::string>{"run", "run.checkpoint.nc"}));

  // Through a symbolic link: the directory it points to changes, the link stays.
  fs::create_directory_symlink("run", dir / "latest");
  {
    RunDirectory run(dir / "latest", RunDirectory::Amend{{"axis_profiles.csv"}});
    write_file(run.staging() / "axis_profiles.csv", "newer axis\n");
    run.publish();
  }
  EXPECT_TRUE(fs::is_symlink(dir / "latest"));
  EXPECT_EQ(read_file(target / "axis_profiles.csv"), "newer axis\n");
  fs::remove(dir / "latest");

  const fs::path fresh = dir / "analysis";  // a missing target is created
  {
    RunDirectory out(fresh, RunDirectory::Amend{{"axis_profiles.csv"}});
    write_file(out.staging() / "axis_profiles.csv", "axis\n");
    out.publish();
  }
  EXPECT_EQ(names_in(fresh), std::set<std::string>{"axis_profiles.csv"});
}

/// The mode and modification time of `path`.
std::pair<fs::perms, std::int64_t> mode_and_mtime(const fs::path& path) {
  struct stat st {};
  EXPECT_EQ(::stat(path.c_str(), &st), 0) << path;
  return {static_cast<fs::perms>(st.st_mode & 07777), static_cast<std::int64_t>(st.st_mtime)};
}

TEST(RunDirectory, AnAmendmentKeepsTheModeAndTimesOfItsDirectories) {
  // The amended directory and each one in it are made anew: a private run
  // directory (700) came out world-readable (755).
  TempDir dir;
  const fs::path target = dir / "run";
  write_earlier_run(target);
  fs::create_directories(target / "gauss" / "deep");
  write_file(target / "gauss" / "spike_profiles.csv", "gauss\n");
  const struct timespec old_time = {1577836800, 0};  // 2020-01-01
  const std::array<timespec, 2> times = {old_time, old_time};
  for (const fs::path& d : {target / "gauss" / "deep", target / "gauss", target}) {
    fs::permissions(d, fs::perms::owner_all);
    ASSERT_EQ(::utimensat(AT_FDCWD, d.c_str(), times.data(), 0), 0);
  }
  fs::permissions(target / "gauss" / "deep", fs::perms::owner_read | fs::perms::owner_exec);
  const auto before = mode_and_mtime(target / "gauss");
  {
    RunDirectory run(target, RunDirectory::Amend{{"axis_profiles.csv"}});
    write_file(run.staging() / "axis_profiles.csv", "axis\n");
    run.publish();
  }
  EXPECT_EQ(mode_and_mtime(target / "gauss"), before);
  EXPECT_EQ(mode_and_mtime(target / "gauss" / "deep").first,
            fs::perms::owner_read | fs::perms::owner_exec);
  EXPECT_EQ(mode_and_mtime(target).first, fs::perms::owner_all);
  EXPECT_EQ(read_file(target / "gauss" / "spike_profiles.csv"), "gauss\n");
  fs::permissions(target / "gauss" / "deep", fs::perms::owner_all);  // for TempDir's removal
}

TEST(RunDirectory, ARunKeepsTheModeOfTheDirectoryItReplaces) {
  // A rerun into a private run directory (700) made it world-readable (755).
  TempDir dir;
  const fs::path target = dir / "run";
  write_earlier_run(target);
  const fs::perms private_mode =
      fs::perms::owner_all | fs::perms::group_read | fs::perms::group_exec | fs::perms::set_gid;
  fs::permissions(target, private_mode);
  {
    RunDirectory run(target);
    write_file(run.staging() / "run.json", "{}");
    run.publish();
  }
  EXPECT_EQ(mode_and_mtime(target).first, private_mode);
  EXPECT_EQ(read_file(target / "run.json"), "{}");
}

TEST(RunDirectory, RefusesTheWorkingDirectoryOrOneThatHoldsIt) {
  // The swap gives DIR a new inode: a shell working in it is left in a deleted directory.
  TempDir dir;
  const fs::path target = dir / "run";
  write_earlier_run(target);
  fs::create_directories(target / "gauss");
  write_file(target / "gauss" / "spike_profiles.csv", "x");  // ehlsim spike --out run/gauss
  const fs::path home = fs::current_path();
  const auto refusal = [&](const fs::path& cwd, const fs::path& out, bool amend) {
    fs::current_path(cwd);
    std::string message = "accepted";
    try {
      if (amend) {
        RunDirectory run(out, RunDirectory::Amend{{"axis_profiles.csv"}});
      } else {
        RunDirectory run(out);
      }
    } catch (const ConfigError& e) {
      message = e.what();
    }
    fs::current_path(home);
    return message;
  };
  const std::string why =
      "' is the working directory or holds it: ehlsim replaces the directory as a whole, which "
      "would leave this shell in a deleted one; run ehlsim from outside it";
  EXPECT_EQ(refusal(target, ".", true), "--out '." + why);
  EXPECT_EQ(refusal(target / "gauss", target, false), "--out '" + target.string() + why);
  EXPECT_EQ(refusal(dir.path(), "run", true), "accepted");
  EXPECT_EQ(refusal(target, dir / "elsewhere", false), "accepted");
}

TEST(RunDirectory, APathWithABackslashIsBadInput) {
  // libnetcdf reads the backslash as a separator: the run failed at its
  // first NetCDF file, after the lock and the staging directory, with exit 1.
  TempDir dir;
  const fs::path target = dir / "a\\b";
  try {
    RunDirectory run(target);
    FAIL() << "accepted";
  } catch (const ConfigError& e) {
    EXPECT_EQ(std::string(e.what()),
              "--out '" + target.string() + "': the path '" + target.string() +
                  "' holds a backslash, which the NetCDF library reads as a directory "
                  "separator: choose a path without one");
  }
  EXPECT_TRUE(fs::is_empty(dir.path()));
  // ... also one behind a link, which the run writes through.
  fs::create_directory(dir / "x\\y");
  fs::create_directory_symlink("x\\y", dir / "lnk");
  try {
    RunDirectory run(dir / "lnk" / "run");
    FAIL() << "accepted";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("the path '" + (dir / "x\\y" / "run").string() +
                                         "' holds a backslash"),
              std::string::npos)
        << e.what();
  }
}

TEST(RunDirectory, ARelativeDirectoryInADeletedWorkingDirectoryIsBadInput) {
  // getcwd(3) fails there: "filesystem error: cannot make absolute path", exit 1.
  TempDir dir;
  const fs::path home = fs::current_path();
  fs::create_directory(dir / "gone");
  fs::current_path(dir / "gone");
  fs::remove(dir / "gone");
  std::string message = "accepted";
  try {
    RunDirectory run("run");
  } catch (const ConfigError& e) {
    message = e.what();
  }
  fs::current_path(home);
  EXPECT_EQ(message,
            "--out 'run': the working directory is unknown (No such file or directory; was it "
            "deleted?): give --out as an absolute path, or run from an existing directory");
}

TEST(RunDirectory, ASignalBeforeTheSwapLeavesTheTargetAsItWas) {
  TempDir dir;
  const fs::path target = dir / "run";
  write_earlier_run(target);
  const InterruptGuard interrupts;
  for (const bool amend : {false, true}) {
    {
      std::optional<RunDirectory> run;
      if (amend) {
        run.emplace(target, RunDirectory::Amend{{"timeseries.csv"}});
      } else {
        run.emplace(target);
      }
      write_file(run->staging() / "timeseries.csv", "new\n");
      std::raise(SIGTERM);
      try {
        run->publish();
        FAIL() << "published after SIGTERM";
      } catch (const PublishInterrupted& e) {
        EXPECT_EQ(e.signal, SIGTERM);
      }
      EXPECT_FALSE(run->published());
    }
    EXPECT_EQ(read_file(target / "timeseries.csv"), "old\n");
    EXPECT_EQ(names_in(dir.path()), std::set<std::string>{"run"});  // staging and lock gone
  }
  const InterruptGuard clear;  // the flag outlives a guard: no later test may see it
}

TEST(PathLock, ASecondLockNamesTheHolderAndTheLockGoesWithIt) {
  TempDir dir;
  const fs::path target = dir / "run";
  {
    const PathLock first(target, "run");
    EXPECT_EQ(first.path(), dir / ".run.lock");
    try {
      const PathLock second(target, "run");
      FAIL() << "a second lock was granted";
    } catch (const ConfigError& e) {
      const std::string text = e.what();
      EXPECT_TRUE(text.starts_with("--out 'run' is in use by another ehlsim run (pid " +
                                   std::to_string(getpid()) + " on host "))
          << text;
      EXPECT_NE(text.find(", started 20"), std::string::npos) << text;
    }
  }
  EXPECT_FALSE(fs::exists(dir / ".run.lock"));
  const PathLock again(target, "run");  // free again
}

TEST(Interrupt, ASignalSetsTheFlagInsteadOfEndingTheProcess) {
  EXPECT_EQ(exit_code_for_signal(SIGINT), 130);
  EXPECT_EQ(exit_code_for_signal(SIGTERM), 143);
  EXPECT_EQ(exit_code_for_signal(SIGHUP), 129);
  EXPECT_EQ(signal_name(SIGHUP), "SIGHUP");
  EXPECT_EQ(signal_name(SIGSEGV), "SIGSEGV");  // a child's crash (io/IsolatedIo.hpp)
  {
    const InterruptGuard guard;
    const StopOnSignal stop;
    EXPECT_EQ(InterruptGuard::received(), 0);
    EXPECT_FALSE(stop.stop_requested());
    std::raise(SIGTERM);
    std::raise(SIGINT);  // the first signal is the one reported
    EXPECT_EQ(InterruptGuard::received(), SIGTERM);
    EXPECT_TRUE(stop.stop_requested());
  }
  const InterruptGuard fresh;
  EXPECT_EQ(InterruptGuard::received(), 0);
}

}  // namespace
}  // namespace ehlsim

// ---------------------------------------------------------------- thread budget

namespace {
using ehlsim::read_runnable_tasks;
using ehlsim::RunnableTasks;
using ehlsim::ThreadBudget;
}  // namespace

TEST(ThreadBudget, UsesTheCoresOtherProcessesLeaveFree) {
  // Two cores.  Alone (only our own threads runnable): both.  One other
  // busy process: one thread.  Three others: still one.  The decision
  // follows the mean of the last five samples, so a single busy sample does
  // not shrink the team, and the team grows back once the others are gone.
  ThreadBudget budget(2, read_runnable_tasks, [](int) {});
  EXPECT_EQ(budget.update({2, 2}), 2);
  for (int k = 0; k < 5; ++k) budget.update({2, 1});  // one other task, our second thread asleep
  EXPECT_EQ(budget.threads(), 1);
  for (int k = 0; k < 5; ++k) budget.update({4, 1});
  EXPECT_EQ(budget.threads(), 1);
  for (int k = 0; k < 5; ++k) budget.update({1, 1});
  EXPECT_EQ(budget.threads(), 2);
  budget.update({2, 1});  // one busy sample among four quiet ones
  EXPECT_EQ(budget.threads(), 2);
  // No /proc: the team stays as it is.
  EXPECT_EQ(budget.update({-1, -1}), 2);
}

// A run reports no step during its solve at T = 0 (seconds on the finest
// grids); the budget samples on every cycle as well, there and within a step.
TEST(ThreadBudget, SamplesWithinTheSolveAtTZeroAndWithinAStep) {
  const auto two_others = [] { return RunnableTasks{3, 1}; };
  int applied = 0;
  ThreadBudget at_t_zero(2, two_others, [&](int n) { applied = n; });
  at_t_zero.on_initial_cycle(1, 0.5);
  EXPECT_EQ(at_t_zero.threads(), 1);
  EXPECT_EQ(applied, 1);
  applied = 0;
  ThreadBudget in_a_step(2, two_others, [&](int n) { applied = n; });
  in_a_step.on_cycle(ehlsim::CycleRecord{});
  EXPECT_EQ(in_a_step.threads(), 1);
  EXPECT_EQ(applied, 1);
}

// OMP_NUM_THREADS is the user's input: a team of at most the cores (100000
// crashed libgomp), and a value libgomp ignores is refused.
TEST(ThreadBudget, TheUsersThreadCountIsAWholeNumberOfAtMostTheCores) {
  using ehlsim::user_thread_count;
  EXPECT_EQ(user_thread_count("1", 2), 1);
  EXPECT_EQ(user_thread_count(" 2 ", 2), 2);
  EXPECT_EQ(user_thread_count("2,1", 4), 2);  // one per nesting level: the first
  EXPECT_EQ(user_thread_count("100000", 2), 2);
  EXPECT_EQ(user_thread_count("99999999999999999999999", 2), 2);
  for (const char* bad : {"", " ", "0", "-1", "abc", "2.5", "+2", "2x", "-99999999999999999999"}) {
    try {
      (void)user_thread_count(bad, 2);
      ADD_FAILURE() << "accepted '" << bad << "'";
    } catch (const ehlsim::ConfigError& e) {
      EXPECT_EQ(std::string(e.what()),
                fmt::format("OMP_NUM_THREADS = '{}': must be a whole number of threads >= 1 "
                            "(unset: ehlsim chooses them from the cores that are free)",
                            bad));
      EXPECT_EQ(e.key(), "OMP_NUM_THREADS");
    }
  }
}

TEST(ThreadBudget, ReadsThisMachine) {
  const RunnableTasks tasks = read_runnable_tasks();
  // This test's own thread is running while it reads.
  EXPECT_GE(tasks.own, 1);
  EXPECT_GE(tasks.machine, tasks.own);
}
