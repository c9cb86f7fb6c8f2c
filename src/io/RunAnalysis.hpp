#pragma once
// `ehlsim spike RUN_DIR`: the spike analysis of every snapshot of a finished
// run (fields.nc, with Delta0, V0 and the spike.* settings from run.json),
// written as spike_snapshots.csv, spike_profiles.csv and axis_profiles.csv
// (io/SpikeWriter.hpp).
#include <cstddef>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace ehlsim {

struct RunAnalysisReport {
  std::size_t snapshots = 0;
  std::vector<std::filesystem::path> files;
  std::vector<std::string> warnings;  ///< what the user should know of the analysis
};

inline constexpr const char* kSpikeSnapshotsFile = "spike_snapshots.csv";
inline constexpr const char* kSpikeProfilesFile = "spike_profiles.csv";
inline constexpr const char* kAxisProfilesFile = "axis_profiles.csv";

/// The run.json at `path`.  Throws ConfigError naming the file when it is
/// missing (the run did not finish), not JSON or not readable (a missing
/// permission), SystemFailure when the machine failed to open it (EMFILE).
[[nodiscard]] nlohmann::json read_run_json(const std::filesystem::path& path);

/// Analyses `run_dir` into `out_dir` (created if missing; may be `run_dir`)
/// as one transaction (io/RunDirectory.hpp, an amendment): a reader of
/// `out_dir` sees its earlier three files or the three new ones, never a mix,
/// and nothing else in `out_dir` changes.  `out_dir` is locked meanwhile.
/// `overrides` are "spike.key=value" assignments applied after the run's own
/// spike settings.  Throws ConfigError (a bad input: no such directory, no
/// complete run in it, an unreadable fields.nc or run.json, a key outside
/// [spike], a bad value, a busy `out_dir`), std::runtime_error (the output
/// cannot be written; SystemFailure where the machine failed to read the
/// input, config/SystemFailure.hpp), RunInterrupted (a signal during the analysis, or while
/// fields.nc is read in a child process first: io/IsolatedIo.hpp) or
/// PublishInterrupted (a signal before the swap); then `out_dir` is as it was.
RunAnalysisReport analyze_run_directory(const std::filesystem::path& run_dir,
                                        const std::filesystem::path& out_dir,
                                        const std::vector<std::string>& overrides);

}  // namespace ehlsim
