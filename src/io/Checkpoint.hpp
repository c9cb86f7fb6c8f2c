#pragma once
// Checkpoints of an impact run: the state at the end of a time step
// (impact/ImpactState.hpp) in a NetCDF-4 file, so that a long run can be
// continued after an interruption, or a hard phase of the run (the spike,
// the end of the rebound) be solved again with other solver settings without
// repeating the approach.
//
//   checkpoint.nc   variables P, P_before, rhoH, rhoH_before (y, x); the ball,
//                   the force history and the summary so far as attributes;
//                   the effective parameters as the JSON attribute
//                   "ehlsim_parameters".
//
// The file is written under a temporary name and renamed: a checkpoint on
// disk is always complete, and the last one survives a run that fails later.
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>

#include "impact/ImpactState.hpp"

namespace ehlsim {

struct Checkpoint {
  ImpactState state;
  nlohmann::json parameters;  ///< effective parameters of the run that wrote it
  /// The source revision of the build that wrote it (io/ProgramInfo.hpp);
  /// "unknown" for a checkpoint of a build that did not record it.  Not
  /// covered by the checksum: it says where the file came from, not what it holds.
  std::string revision;
};

inline constexpr const char* kCheckpointFile = "checkpoint.nc";

/// Writes `state` and `parameters` to `path` (atomically).  Throws
/// std::runtime_error when the file cannot be written.
void write_checkpoint(const std::filesystem::path& path, const ImpactState& state,
                      const nlohmann::json& parameters);

/// Reads a checkpoint.  Throws std::runtime_error naming the file when it
/// cannot be read or is not an ehlsim checkpoint.
[[nodiscard]] Checkpoint read_checkpoint(const std::filesystem::path& path);

/// read_checkpoint of a file from outside this process (`ehlsim impact
/// --restart`): read in a child process first (io/IsolatedIo.hpp), so that
/// a file HDF5 crashes or hangs on gives a std::runtime_error naming it too.
/// Throws PreReadInterrupted after a signal during that read.
[[nodiscard]] Checkpoint read_untrusted_checkpoint(const std::filesystem::path& path);

/// What a restart may change, in words (check_restart_compatible).
inline constexpr const char* kRestartMayChange =
    "solver.*, output.*, spike.*, time.T_end and time.max_steps";

/// A restart continues the same case: every effective parameter must be the
/// checkpoint's, except those of the solver (not solver.face_mean, which
/// changes the discrete problem), the output, the spike analysis,
/// time.T_end and time.max_steps.  Throws ConfigError naming the first key that differs, e.g.
/// "grid.points = 257, but checkpoint 'c.nc' was written with 513 (...)".
void check_restart_compatible(const nlohmann::json& checkpoint_parameters,
                              const nlohmann::json& parameters, const std::string& file);

}  // namespace ehlsim
