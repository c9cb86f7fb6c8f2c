#include "io/RunAnalysis.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <span>

#include "analysis/SpikeAnalysis.hpp"
#include "config/Parameters.hpp"
#include "config/SystemFailure.hpp"
#include "grid/FieldExtrema.hpp"
#include "impact/RunGuards.hpp"
#include "io/FieldReader.hpp"
#include "io/Interrupt.hpp"
#include "io/IsolatedIo.hpp"
#include "io/RangeCheckedJson.hpp"
#include "io/RunDirectory.hpp"
#include "io/RunOutput.hpp"
#include "io/SpikeWriter.hpp"

namespace ehlsim {

nlohmann::json read_run_json(const std::filesystem::path& path) {
  // Only a regular file: opening a FIFO waits for a writer that never comes,
  // and a directory failed in the parser with no path named.
  std::error_code ec;
  const bool regular = std::filesystem::is_regular_file(path, ec);
  const bool missing =
      ec == std::errc::no_such_file_or_directory || ec == std::errc::not_a_directory;
  if (!regular && (!ec || missing)) {
    throw ConfigError(
        fmt::format("cannot read '{}': not a complete ehlsim run directory (run.json "
                    "is written last, when the run has finished)",
                    path.string()));
  }
  // Any other failure says why: every one was "not a complete ehlsim run
  // directory", a missing permission (exit 2) and EMFILE (exit 1) alike.
  if (ec) throw_unreadable_input(path, ec.value());
  errno = 0;
  std::ifstream in(path);  // libstdc++ opens with fopen, which sets errno
  if (!in) throw_unreadable_input(path, errno != 0 ? errno : EIO);
  try {
    return parse_range_checked_json(in, path.string());
  } catch (const std::ios_base::failure&) {
    // A read that failed (EIO) was "basic_filebuf::underflow error reading the file", no path.
    throw_unreadable_input(path, errno != 0 ? errno : EIO);
  }
}

namespace {

constexpr std::string_view kSpikeSection = "spike.";

/// The run's spike settings as overrides.  Not the defaults where run.json
/// has none: every impact run records its own, and an analysis with other
/// settings than the run's reported them as the run's.
std::vector<std::string> recorded_spike_settings(const nlohmann::json& run,
                                                 const std::filesystem::path& run_file) {
  const auto parameters = run.find("parameters");
  if (parameters == run.end() || !parameters->is_object() || !parameters->contains("spike") ||
      !parameters->at("spike").is_object()) {
    throw ConfigError(fmt::format(
        "cannot read '{}': no table parameters.spike (the run's spike settings, which every run "
        "of ehlsim impact records)",
        run_file.string()));
  }
  const nlohmann::json& settings = parameters->at("spike");
  // Each of them: one missing was analysed with its default.
  const nlohmann::json defaults = effective_parameters_json(load_config(std::nullopt, {}));
  for (const auto& [key, value] : defaults.at("spike").items()) {
    if (!settings.contains(key))
      throw ConfigError(
          fmt::format("cannot read '{}': parameters.spike has no {} (every run of "
                      "ehlsim impact records each spike setting)",
                      run_file.string(), key));
  }
  std::vector<std::string> out;
  for (auto it = settings.begin(); it != settings.end(); ++it) {
    // Neither is a TOML value: read as text, they were shown quoted ("null").
    if (it.value().is_null() || it.value().is_structured())
      throw ConfigError(fmt::format(
          "cannot read '{}': parameters.spike.{} is {}, not the value of a setting (a number "
          "or a text)",
          run_file.string(), echo_input(it.key()),
          it.value().is_null() ? "null" : echo_input(it.value().dump())));
    out.push_back(fmt::format("{}{}={}", kSpikeSection, it.key(), it.value().dump()));
  }
  return out;
}

/// The run's spike settings as overrides, then the caller's (spike.* only):
/// a bad value of the run's is named as run.json's, not as --set.
std::vector<std::string> spike_overrides(const nlohmann::json& run,
                                         const std::vector<std::string>& extra,
                                         const std::filesystem::path& run_file) {
  std::vector<std::string> out = recorded_spike_settings(run, run_file);
  (void)load_config(std::nullopt, out, fmt::format("parameters of '{}'", run_file.string()));
  for (const std::string& assignment : extra) {
    if (assignment.rfind(kSpikeSection, 0) != 0) {
      throw ConfigError(
          fmt::format("--set '{}': only spike.* keys apply to an analysis of a "
                      "finished run",
                      echo_input(assignment)));
    }
    out.push_back(assignment);
  }
  return out;
}

/// Throws ConfigError when run.json says that another command wrote it
/// (`ehlsim rolling` writes one too); without the key the parameters decide.
void check_impact_run(const nlohmann::json& run, const std::filesystem::path& path) {
  if (!run.is_object()) return;
  const auto program = run.find("program");
  if (program == run.end()) return;
  if (!program->is_object())
    throw ConfigError(fmt::format("cannot read '{}': program is {}, not a table", path.string(),
                                  echo_input(program->dump())));
  const auto command = program->find("command");
  if (command != program->end() && !command->is_string())
    throw ConfigError(
        fmt::format("cannot read '{}': program.command is {}, not the name of a command",
                    path.string(), echo_input(command->dump())));
  if (command == program->end() || *command == "impact") return;
  throw ConfigError(fmt::format(
      "cannot analyse '{}': a run of `ehlsim {}`; ehlsim spike analyses runs of `ehlsim impact`",
      path.string(), echo_input(command->get<std::string>())));
}

double run_parameter(const nlohmann::json& run, const char* section, const char* key,
                     const std::filesystem::path& path) {
  try {
    return run.at("parameters").at(section).at(key).get<double>();
  } catch (const nlohmann::json::exception&) {
    throw ConfigError(
        fmt::format("cannot read '{}': no number parameters.{}.{}", path.string(), section, key));
  }
}

/// The run's surface.waviness_amplitude, or 0 where run.json has no number
/// there (the analysis needs none: it only warns of a wavy surface).
double recorded_waviness(const nlohmann::json& run) {
  const nlohmann::json* value = &run;
  for (const char* key : {"parameters", "surface", "waviness_amplitude"}) {
    if (!value->is_object() || !value->contains(key)) return 0.0;
    value = &value->at(key);
  }
  return value->is_number() ? value->get<double>() : 0.0;
}

/// Opens the fields.nc of a run, read in a child process first (a file HDF5
/// crashes or hangs on is named like any other damaged one).  Throws
/// ConfigError for a file that cannot be read or holds no snapshot,
/// SystemFailure where the machine failed (no descriptor for the child's
/// pipe), RunInterrupted for a signal during the child's read (the analysis
/// has not started).
std::unique_ptr<FieldReader> open_fields(const std::filesystem::path& path) {
  std::unique_ptr<FieldReader> fields;
  try {
    pre_read_fields_in_child(path);
    fields = std::make_unique<FieldReader>(path);
  } catch (const PreReadInterrupted&) {
    throw RunInterrupted(0, std::numeric_limits<double>::quiet_NaN());
  } catch (const SystemFailure&) {
    throw;  // exit 1: out of descriptors ("pipe: Too many open files") is no bad file
  } catch (const std::runtime_error& e) {
    throw_if_machine_cannot_read(path);  // "NetCDF: HDF error" over a failing disk
    throw ConfigError(e.what());
  }
  // Every run stores its last step: an empty file gave CSV headers alone, exit 0.
  if (fields->times().empty())
    throw ConfigError(
        fmt::format("cannot use '{}': it holds no snapshot (time has length 0; every "
                    "run stores at least its last step)",
                    path.string()));
  return fields;
}

/// The largest pressure a snapshot may hold: far above any run's (the pocket
/// collapse peaks at 42 on 1025^2, docs/performance.md), far below where the
/// filter's sums overflow (P = 1e308 everywhere gave -nan in
/// spike_profiles.csv, with exit 0).
constexpr double kMaxSnapshotPressure = 1e100;

/// Snapshot `k` of the fields file `path` (pressure P at time T, after
/// `previous`) as a run writes one: a time later than the one before, and
/// pressures that are finite and >= 0.  Throws ConfigError naming the file: a
/// damaged fields.nc gave exit 0 with NaN in spike.csv.
void check_snapshot(const std::filesystem::path& path, std::size_t k, double T, double previous,
                    const Field& P) {
  if (!std::isfinite(T) || !(T > previous)) {
    throw ConfigError(fmt::format(
        "cannot use '{}': snapshot {} has time {} (the times of a run are finite and increasing; "
        "the one before is {})",
        path.string(), k, T, previous));
  }
  if (const auto unsound = first_unsound_point(P, [](int, int) { return true; })) {
    throw ConfigError(fmt::format(
        "cannot use '{}': snapshot {} (T = {:g}) has the pressure {} at point ({}, {}) (a run "
        "writes finite pressures >= 0)",
        path.string(), k, T, unsound->value, unsound->i, unsound->j));
  }
  const std::span<const double> values = P.span();
  if (const double peak = *std::max_element(values.begin(), values.end());
      peak > kMaxSnapshotPressure) {
    throw ConfigError(
        fmt::format("cannot use '{}': snapshot {} (T = {:g}) has the pressure {:g} (no run's is "
                    "above {:g})",
                    path.string(), k, T, peak, kMaxSnapshotPressure));
  }
}

/// Snapshot `k`'s pressure from `fields`, read from `path`; ConfigError (bad
/// input) when the file's data cannot be read (bytes of a fields.nc
/// overwritten: "NetCDF: HDF error"), SystemFailure when the disk cannot.
Field read_pressure(const FieldReader& fields, const std::filesystem::path& path, std::size_t k) {
  try {
    return fields.pressure(k);
  } catch (const SystemFailure&) {
    throw;
  } catch (const std::runtime_error& e) {
    throw_if_machine_cannot_read(path);
    throw ConfigError(e.what());
  }
}

/// The dry contact of a run's start; ConfigError when run.json's values
/// give none (Delta0 = 1e308: "the implicit step did not converge", exit 1).
DryContactRadius dry_contact_of(double Delta0, double V0, const std::filesystem::path& run_file) {
  try {
    return DryContactRadius(Delta0, V0);
  } catch (const std::runtime_error& e) {
    throw ConfigError(
        fmt::format("cannot use '{}': parameters.time Delta0 = {} and V0 = {} give "
                    "no dry contact to compare with ({})",
                    run_file.string(), Delta0, V0, e.what()));
  }
}

/// The analysis of `run_dir` written into the directory `staging`.
RunAnalysisReport write_analysis(const std::filesystem::path& run_dir,
                                 const std::filesystem::path& staging,
                                 const std::vector<std::string>& overrides) {
  const std::filesystem::path run_file = run_dir / RunOutput::kRunFile;
  const nlohmann::json run = read_run_json(run_file);
  check_impact_run(run, run_file);
  const SpikeSettings settings =
      load_config(std::nullopt, spike_overrides(run, overrides, run_file)).spike;
  const double Delta0 = run_parameter(run, "time", "Delta0", run_file);
  const double V0 = run_parameter(run, "time", "V0", run_file);
  // A run's own start (time.V0 = 0 in an edited run.json failed in Newmark, exit 1).
  if (!(Delta0 > 0.0 && V0 >= kMinV0 && V0 <= kMaxV0))
    throw ConfigError(
        fmt::format("cannot use '{}': parameters.time Delta0 = {} and V0 = {} are "
                    "no run's (Delta0 > 0, V0 in [{:g}, {:g}])",
                    run_file.string(), Delta0, V0, kMinV0, kMaxV0));
  const DryContactRadius dry = dry_contact_of(Delta0, V0, run_file);

  const std::unique_ptr<FieldReader> fields = open_fields(run_dir / RunOutput::kFieldsFile);

  RunAnalysisReport report;
  if (std::string note = spike_note(recorded_waviness(run)); !note.empty())
    report.warnings.push_back(std::move(note));
  report.files = {staging / kSpikeSnapshotsFile, staging / kSpikeProfilesFile,
                  staging / kAxisProfilesFile};
  SpikeSeriesWriter series(report.files[0]);
  ProfileWriter radial(report.files[1], "T,R,P_filtered");
  ProfileWriter axis(report.files[2], "T,X,P");
  const RadialOrder order(fields->grid());
  double previous = -std::numeric_limits<double>::infinity();
  for (std::size_t k = 0; k < fields->times().size(); ++k) {
    const double T = fields->times()[k];
    // A signal: stop before anything is published (the staging directory goes).
    if (InterruptGuard::received() != 0) throw RunInterrupted(static_cast<int>(k), T);
    const Field P = read_pressure(*fields, run_dir / RunOutput::kFieldsFile, k);
    check_snapshot(run_dir / RunOutput::kFieldsFile, k, T, previous, P);
    previous = T;
    const SpikeAnalysis analysis = analyze_spike(order, P.span(), settings);
    series.append(spike_sample(T, analysis, dry));
    radial.append(T, analysis.filtered);
    axis.append(T, analysis.axis);
    ++report.snapshots;
    if (k == 0) stop_here_for_tests("analysis");
  }
  series.commit();
  radial.commit();
  axis.commit();
  return report;
}

/// The spike files of a run go into the run directory itself, or into a
/// directory of their own: not beside another run's results (they would
/// describe a run that is not there), nor into a directory that holds the
/// run (the amendment would make the whole tree anew).
void check_spike_out(const std::filesystem::path& run_dir, const std::filesystem::path& out_dir) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (!fs::is_directory(out_dir, ec) || !fs::is_directory(run_dir, ec)) return;
  if (fs::equivalent(out_dir, run_dir, ec)) return;
  const char* where =
      "the run directory (the default) or a directory of their own, such as RUN/gauss";
  if (holds_path(out_dir, run_dir)) {
    throw ConfigError(fmt::format("--out '{}' holds the run directory '{}': the spike files go "
                                  "into {}",
                                  out_dir.string(), run_dir.string(), where),
                      "--out");
  }
  if (fs::exists(out_dir / RunOutput::kRunFile, ec)) {
    throw ConfigError(fmt::format("--out '{}' is another run's directory (it holds a run.json): "
                                  "the spike files of '{}' go into {}",
                                  out_dir.string(), run_dir.string(), where),
                      "--out");
  }
}

}  // namespace

namespace {
/// Refuses `dir` (RUN_DIR or --out, named as `what`) when it is the staging
/// directory of a run: analysed and swapped, it had a run in progress publish
/// files it never wrote.
void refuse_staging_directory(const std::filesystem::path& dir, std::string_view what) {
  const std::optional<std::filesystem::path> run = run_directory_staged_in(dir);
  if (!run) return;
  throw ConfigError(
      fmt::format("{} '{}' is the staging directory of an ehlsim run into '{}', one being "
                  "written or left by a killed one: ehlsim spike reads and amends finished "
                  "runs only; use '{}' once that run has ended",
                  what, dir.string(), run->string(), run->string()),
      what == "--out" ? "--out" : "");
}

/// OUT, locked for the analysis.  Where it cannot be (`ehlsim spike
/// /proc/self`: no lock file can be made beside it, exit 1) and RUN_DIR holds
/// no run.json, the bad input is said instead: no run directory was given.
std::unique_ptr<RunDirectory> lock_spike_out(const std::filesystem::path& run_dir,
                                             const std::filesystem::path& out_dir) {
  // A run.json that is a FIFO is no complete run, before the amendment of
  // RUN_DIR names it as an entry it cannot carry over.
  const std::filesystem::path run_file = run_dir / RunOutput::kRunFile;
  std::error_code ec;
  if (std::filesystem::exists(std::filesystem::symlink_status(run_file, ec)) &&
      !std::filesystem::is_regular_file(run_file, ec))
    (void)read_run_json(run_file);  // throws its ConfigError
  try {
    return std::make_unique<RunDirectory>(
        out_dir, RunDirectory::Amend{{kSpikeSnapshotsFile, kSpikeProfilesFile, kAxisProfilesFile}});
  } catch (const ConfigError&) {
    throw;
  } catch (const std::runtime_error&) {
    if (!std::filesystem::is_regular_file(run_file, ec))
      (void)read_run_json(run_file);  // throws its ConfigError
    throw;
  }
}
}  // namespace

RunAnalysisReport analyze_run_directory(const std::filesystem::path& run_dir,
                                        const std::filesystem::path& out_dir,
                                        const std::vector<std::string>& overrides) {
  const auto refuse_run_dir = [&] {
    throw ConfigError(
        fmt::format("run directory '{}' does not exist or is not a directory", run_dir.string()));
  };
  // A file or a link loop given as RUN_DIR, or none (`ehlsim spike "$UNSET"`),
  // is named as such, not as the --out it defaults to.
  std::error_code ec;
  const bool exists = std::filesystem::exists(run_dir, ec);
  if (run_dir.empty() || ec == std::errc::too_many_symbolic_link_levels ||
      (exists && !std::filesystem::is_directory(run_dir, ec)))
    refuse_run_dir();
  refuse_staging_directory(run_dir, "run directory");
  refuse_staging_directory(out_dir, "--out");
  // Then OUT locked (not while an impact run or another analysis writes
  // there; a busy RUN_DIR is named as such, not as missing).
  check_spike_out(run_dir, out_dir);
  const std::unique_ptr<RunDirectory> out = lock_spike_out(run_dir, out_dir);
  if (!std::filesystem::is_directory(run_dir, ec)) refuse_run_dir();
  RunAnalysisReport report = write_analysis(run_dir, out->staging(), overrides);
  out->publish();
  for (std::filesystem::path& file : report.files) file = out_dir / file.filename();
  return report;
}

}  // namespace ehlsim
