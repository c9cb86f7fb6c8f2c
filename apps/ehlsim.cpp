// ehlsim: the command line.
//
//   ehlsim impact [CONFIG.toml] [--out DIR] [--set KEY=VALUE]... [--restart CHECKPOINT] [--quiet]
//   ehlsim impact --help        (lists every parameter with default and range)
//   ehlsim spike RUN_DIR [--out DIR] [--set spike.KEY=VALUE]... [--quiet]
//   ehlsim study [--grid N] [--rolling-grid N] [--out DIR] [--jobs J] [--set K=V]... [--no-plots]
//   ehlsim rolling [CONFIG.toml] [--out DIR] [--set KEY=VALUE]... [--quiet]  (apps/Rolling.cpp)
//   ehlsim --version
//
// Exit codes: 0 success; 1 the run failed (solver, file system); 2 bad input
// (command line, configuration).  Every error is one line on stderr,
// "ehlsim: error: <message>".
//
// Each subcommand is a pair add_<name>_command (options) / run_<name> (action);
// the study driver is in apps/Study.cpp.
#include <fcntl.h>
#include <fmt/format.h>
#include <omp.h>
#include <sys/prctl.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "Cli.hpp"
#include "Rolling.hpp"
#include "Study.hpp"
#include "config/Parameters.hpp"
#include "config/SystemFailure.hpp"
#include "grid/Grid.hpp"
#include "impact/ImpactConfig.hpp"
#include "impact/ImpactProblem.hpp"
#include "impact/RunGuards.hpp"
#include "io/AtomicFile.hpp"
#include "io/Checkpoint.hpp"
#include "io/Interrupt.hpp"
#include "io/IsolatedIo.hpp"
#include "io/MemoryGuard.hpp"
#include "io/ObserverChain.hpp"
#include "io/ProgramInfo.hpp"
#include "io/RunAnalysis.hpp"
#include "io/RunDirectory.hpp"
#include "io/RunOutput.hpp"
#include "io/SpikeWriter.hpp"
#include "io/ThreadBudget.hpp"

namespace {

using namespace ehlsim;

using cli::kExitBadInput;
using cli::kExitFailure;
using cli::kExitOk;
using cli::print_error;
using cli::print_out;

// ---------------------------------------------------------------------------
// ehlsim impact
// ---------------------------------------------------------------------------

struct ImpactOptions : cli::CaseOptions {
  ImpactOptions() { out_dir = "run"; }
  std::string restart_file;        ///< "" = start at Delta0
  std::string program = "ehlsim";  ///< argv[0], for the resume command
};

CLI::App* add_impact_command(CLI::App& app, ImpactOptions& options) {
  CLI::App* cmd = app.add_subcommand(
      "impact", "Simulate one lubricated ball impact on a flat (Lubrecht & Venner 2022).");
  cli::add_case_options(*cmd, options, "the paper's case M = 100, L = 10",
                        "timeseries.csv, fields.nc and run.json");
  cmd->add_option("--restart", options.restart_file,
                  "continue from a checkpoint.nc of the same case (see output.checkpoint_every); "
                  "solver.*, output.*, spike.*, time.T_end and time.max_steps may differ")
      ->check(cli::path_name("a checkpoint file"))
      ->type_name("CHECKPOINT");
  cli::add_quiet_flag(*cmd, options.quiet);
  cmd->footer("\n" + describe_parameters());
  return cmd;
}

void print_case(const ImpactConfig& c, const std::string& out_dir) {
  const Grid2D grid(c.grid_points, c.half_width);
  print_out("ehlsim {} impact -> {}\n", EHLSIM_VERSION, out_dir);
  print_out("  case       M = {:.6g}, L = {:.6g} (lambda_bar = {:.6g}, alpha_bar = {:.6g})\n", c.M,
            c.L, c.lambda_bar, c.alpha_bar);
  if (c.physical) {
    const PhysicalCase& p = *c.physical;
    print_out(
        "  physical   R = {:.4g} m, m = {:.4g} kg, v0 = {:.4g} m/s, E' = {:.4g} Pa, "
        "eta0 = {:.4g} Pa s, alpha = {:.4g} 1/Pa\n",
        p.reduced_radius_m, p.mass_kg, p.impact_speed_m_s, p.reduced_modulus_Pa, p.eta0_Pa_s,
        p.alpha_per_Pa);
    print_out(
        "  scales     delta* = {:.4g} m, a* = {:.4g} m, ph* = {:.4g} Pa, F* = {:.4g} N, "
        "t_bar = {:.4g} s\n",
        p.delta_star_m, p.a_star_m, p.ph_star_Pa, p.F_star_N, p.t_bar_s);
  }
  print_out("  lubricant  {}\n", lubricant_text(c.lubricant));
  print_out("  body       {}{}\n", c.elastic ? "elastic" : "rigid",
            c.waviness_amplitude > 0.0
                ? fmt::format(", waviness A = {:.4g}, wavelength {:.4g}, angle {:.4g} deg",
                              c.waviness_amplitude, c.waviness_wavelength, c.waviness_angle_deg)
                : std::string());
  print_out("  grid       {}^2 on [-{:g}, {:g}]^2, h = {:.6g}{}\n", c.grid_points, c.half_width,
            c.half_width, grid.h(),
            is_mirror_symmetric(c) ? ", solved on the quadrant X, Y >= 0 (mirror symmetry)" : "");
  print_out("  time       dT = {:.6g}, {}, Delta0 = {:g}, V0 = {:g}\n", effective_time_step(c),
            std::isfinite(c.T_end) ? fmt::format("T_end = {:g}", c.T_end) : "until lift-off",
            c.Delta0, c.V0);
  print_out(
      "  solver     {}({},{}) cycles, tolerance {:g}, at most {} cycles/step, coarsest {}^2, "
      "deformation {} (once per {}), lines {}{}\n",
      cycle_type_text(c.cycle), c.pre_sweeps, c.post_sweeps, c.tolerance, c.max_cycles,
      c.coarsest_points, deformation_method_text(c.deformation),
      c.relaxation.deformation_each_colour ? "colour" : "sweep",
      c.relaxation.alternate_directions ? "along X and Y in turn" : "along X",
      c.coarse_face_mean
          ? fmt::format(", {} face mean on the coarse levels", face_mean_text(*c.coarse_face_mean))
          : std::string());
  print_out("  output     fields every {} steps{}\n", c.snapshot_every,
            c.snapshot_times.empty()
                ? std::string()
                : fmt::format(" and at T = {}", fmt::join(c.snapshot_times, ", ")));
  std::fflush(stdout);
}

void print_summary(const RunSummary& s, const RunOutput& output,
                   const std::filesystem::path& directory) {
  switch (s.outcome) {
    case RunOutcome::LiftOff:
      print_out("lift-off at T = {:.6g}, rebound speed {:.6g}\n", s.T_lift_off, s.rebound_speed);
      break;
    case RunOutcome::AtRest:
      print_out(
          "at rest in the film at T = {:.6g}: no rebound (energy left {:.3g} of the "
          "impact energy, dDelta/dT at most {:.3g} V0 from now on)\n",
          s.T_final, s.final_energy, std::sqrt(s.final_energy));
      break;
    case RunOutcome::TEnd:
      print_out("no lift-off by T = {:.6g} (time.T_end)\n", s.T_final);
      break;
  }
  print_out(
      "max force {:.6g} at T = {:.6g}, min central film {:.6g} at T = {:.6g}, impulse {:.6g}\n",
      s.max_force, s.T_max_force, s.min_h_center, s.T_min_h_center, s.impulse);
  print_out("{} steps, {} snapshots, {:.1f} s; output in {}\n", s.steps, output.snapshots_written(),
            output.elapsed_seconds(), directory.string());
  const auto steps = [](int n) { return fmt::format("{} step{}", n, n == 1 ? "" : "s"); };
  if (s.unconverged_steps > 0 || s.retried_steps > 0)
    print_out(
        "{} ended above solver.tolerance (see the residual column of timeseries.csv), {} "
        "solved again with more damping\n",
        steps(s.unconverged_steps), steps(s.retried_steps));
}

/// `arg` for a shell: quoted unless it is made of safe characters only.
std::string shell_word(const std::string& arg) {
  const bool safe = !arg.empty() && std::all_of(arg.begin(), arg.end(), [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) != 0 ||
           std::string_view("_-+=.,:/@%").find(c) != std::string_view::npos;
  });
  if (safe) return arg;
  // A newline or another control character (--out $'nl\nrun') would break the
  // one line: bash's $'...' quoting writes it as an escape (cli::printable's).
  if (cli::printable(arg) != arg) {
    std::string quoted;
    for (const char c : arg) {
      if (c == '\'' || c == '\\') quoted += '\\';
      quoted += c;
    }
    return "$'" + cli::printable(quoted) + "'";
  }
  std::string out = "'";
  for (const char c : arg) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return out + "'";
}

/// The command that continues this run from `checkpoint`.
std::string resume_command(const ImpactOptions& options, const std::filesystem::path& checkpoint) {
  std::vector<std::string> words = {options.program, "impact"};
  // A relative path that starts with '-' would be read as an option (it was given after "--").
  if (!options.config_file.empty())
    words.push_back(options.config_file.starts_with('-') ? "./" + options.config_file
                                                         : options.config_file);
  for (const std::string& o : options.overrides) {
    words.push_back("--set");
    words.push_back(o);
  }
  words.insert(words.end(), {"--out", options.out_dir, "--restart", checkpoint.string()});
  if (options.quiet) words.push_back("--quiet");
  std::string command;
  for (const std::string& w : words) command += (command.empty() ? "" : " ") + shell_word(w);
  return command;
}

/// What the run leaves for a restart when it does not complete: the last
/// checkpoint it wrote, else the one it was restarted from (still there).
struct KeptCheckpoint {
  int step = 0;  ///< 0: none
  std::filesystem::path path;
  double T = 0.0;  ///< its time
  /// An earlier run's DIR.checkpoint.nc that this run, keeping none, left as it was.
  std::filesystem::path spared;
};

/// The last time step a run completed, for the message of a failure that
/// does not name one (a full disk, a file that cannot be written).
class LastStep final : public ImpactObserver {
 public:
  LastStep() = default;
  /// A restart's: it has completed the checkpoint's steps (a failed write
  /// before its first said "before the first time step").
  LastStep(int step, double T) : step_(step), T_(T) {}
  void on_step(const StepRecord& record, const Field&, const Field&, bool) override {
    step_ = record.step;
    T_ = record.T;
  }
  /// "after time step N (T = ...): ", or "before the first time step: ".
  [[nodiscard]] std::string where() const {
    return step_ > 0 ? fmt::format("after time step {} (T = {:.6g}): ", step_, T_)
                     : std::string("before the first time step: ");
  }

 private:
  int step_ = 0;
  double T_ = 0.0;
};

/// Whether the run continues from `checkpoint` itself (--restart of that file).
bool resumes_from(const ImpactOptions& options, const std::filesystem::path& checkpoint) {
  std::error_code ec;  // a file that is not there is not the restart file
  return !options.restart_file.empty() &&
         std::filesystem::equivalent(options.restart_file, checkpoint, ec);
}

/// Starts `problem`, `spike` and `output` where `checkpoint` left off, as the
/// uninterrupted run goes on (V_s of the next step, snapshot times already
/// reached).  A run that keeps checkpoints holds the one it resumes from in
/// its staging directory at once, written from what was read: it is the run's
/// last checkpoint until it writes one (the uninterrupted run has it), and its
/// file may change or go meanwhile (it was published as it was then: another
/// case's, a FIFO, or a run's failure at the end).
void resume(Checkpoint& checkpoint, const ImpactConfig& config, const RunDirectory& run_dir,
            ImpactProblem& problem, SpikeOutput& spike, RunOutput& output) {
  spike.resume_after(checkpoint.state.ball.T, checkpoint.state.P);
  output.resume_after(checkpoint.state.ball.T);
  if (config.checkpoint_every > 0) {
    write_checkpoint(run_dir.staged_checkpoint(), checkpoint.state, checkpoint.parameters);
    output.add_file("checkpoint", kCheckpointFile);
  }
  problem.restart_from(std::move(checkpoint.state));
}

/// Runs the case into the staging directory of `run_dir` and publishes it.
/// Throws RunInterrupted after a signal, with the checkpoint written.
RunSummary simulate(const ImpactOptions& options, const ImpactConfig& config,
                    std::optional<Checkpoint>& checkpoint, RunDirectory& run_dir,
                    const nlohmann::json& invocation, KeptCheckpoint& kept, LastStep& last) {
  const nlohmann::json parameters = effective_parameters_json(config);
  // spike.csv first: run.json, written last by RunOutput, marks a complete run.
  SpikeOutput spike(run_dir.staging(), config);
  RunOutput output(run_dir.staging(), config, !options.quiet, invocation);
  output.add_file("spike", SpikeOutput::kFile);
  // The thread team follows the cores that other processes leave free, unless
  // the user fixed it with OMP_NUM_THREADS (io/ThreadBudget.hpp).
  ThreadBudget threads(omp_get_max_threads());
  StopOnSignal stop;
  std::vector<ImpactObserver*> chain{&last, &spike, &output, &stop};
  if (!user_set_thread_count()) chain.push_back(&threads);
  ObserverChain observers(chain);
  ImpactProblem problem(config);
  if (checkpoint) resume(*checkpoint, config, run_dir, problem, spike, output);
  const bool resumed_beside = resumes_from(options, run_dir.checkpoint());
  // Without checkpoints asked for, a signal's checkpoint would replace an
  // earlier run's, perhaps the only copy of hours of work: that one stays.
  const bool spare_earlier = config.checkpoint_every <= 0 &&
                             std::filesystem::exists(run_dir.checkpoint()) && !resumed_beside;
  if (spare_earlier) kept.spared = run_dir.checkpoint();
  // Checkpoints go to DIR.checkpoint.nc (for a restart after a failure or a
  // kill), and into the staging directory: DIR keeps the earlier run's until
  // this one publishes.
  problem.set_state_sink(config.checkpoint_every, [&](const ImpactState& state) {
    if (spare_earlier) return;
    write_checkpoint(run_dir.checkpoint(), state, parameters);
    // Resumable from it even if the copy into the staging directory fails.
    kept = {state.step, run_dir.checkpoint(), state.ball.T, {}};
    run_dir.stage_checkpoint();
    if (config.checkpoint_every > 0) output.add_file("checkpoint", kCheckpointFile);
  });
  const RunSummary summary = problem.run(observers);
  if (!output.committed()) observers.on_finish(summary);
  run_dir.publish(resumed_beside);
  if (!options.quiet) {
    print_summary(summary, output, run_dir.target());
    cli::print_warnings(summary.warnings);
  }
  return summary;
}

/// The one line of a run stopped by `signal` after its last step, before the
/// swap (io/RunDirectory.hpp); its exit code.
int report_unpublished(const ImpactOptions& options, const ImpactConfig& config,
                       const KeptCheckpoint& kept, int signal) {
  // A checkpoint of the run's last step leaves no step to resume: its resume
  // command was refused ("time.T_end = 1: must be later than the time of checkpoint").
  const bool last =
      (std::isfinite(config.T_end) && !(config.T_end > kept.T)) ||
      (!std::isfinite(config.T_end) && config.max_steps > 0 && config.max_steps <= kept.step);
  std::string next = fmt::format("resume from the checkpoint of step {} with: {}", kept.step,
                                 resume_command(options, kept.path));
  if (kept.step == 0) next = "no checkpoint was written: run the command again";
  if (kept.step > 0 && last)
    next = fmt::format(
        "its checkpoint is of its last step ({}), which leaves nothing to resume: run the "
        "command again",
        kept.step);
  std::fprintf(stderr,
               "ehlsim: interrupted by %s after the last step, before the run was published: "
               "'%s' was not changed; %s\n",
               signal_name(signal).c_str(), cli::printable(options.out_dir).c_str(), next.c_str());
  return exit_code_for_signal(signal);
}

/// What run.json records under "invocation".
nlohmann::json impact_invocation_json(const ImpactOptions& options,
                                      const std::optional<Checkpoint>& checkpoint,
                                      const MemoryBudget& memory) {
  nlohmann::json invocation = cli::invocation_json(options, memory_json(memory));
  if (checkpoint)
    invocation["restart"] = {{"checkpoint", options.restart_file},
                             {"step", checkpoint->state.step},
                             {"T", checkpoint->state.ball.T},
                             {"revision", checkpoint->revision}};
  return invocation;
}

/// Reads the checkpoint of --restart into `checkpoint` (in a child process
/// first: io/IsolatedIo.hpp) and checks that it continues `config`'s case.
/// Returns kExitOk, or the exit code after its one line: 2 for a file that
/// cannot be read (damaged, or one the NetCDF/HDF5 library crashes or hangs
/// on), 128 + the signal for a signal meanwhile.  Throws ConfigError for a
/// checkpoint of another case.
int read_restart_checkpoint(const ImpactOptions& options, const ImpactConfig& config,
                            std::optional<Checkpoint>& checkpoint) {
  try {
    checkpoint = read_untrusted_checkpoint(options.restart_file);
  } catch (const PreReadInterrupted& e) {
    std::fprintf(stderr,
                 "ehlsim: interrupted by %s while checkpoint '%s' was read, before the run "
                 "started: '%s' was not changed; run the command again\n",
                 signal_name(e.signal).c_str(), cli::printable(options.restart_file).c_str(),
                 cli::printable(options.out_dir).c_str());
    return exit_code_for_signal(e.signal);
  } catch (const SystemFailure&) {
    throw;  // exit 1: "pipe: Too many open files" is no damaged checkpoint
  } catch (const std::runtime_error& e) {
    throw_if_machine_cannot_read(options.restart_file);  // a failing disk: exit 1
    print_error(e.what());  // names the file, and the field of a damaged one
    return kExitBadInput;
  }
  check_restart_compatible(checkpoint->parameters, effective_parameters_json(config),
                           options.restart_file);
  // A run to a time the checkpoint has passed ran one step and ended at
  // once, with exit 0 (time.T_end = 3 from T = 4).
  if (std::isfinite(config.T_end) && !(config.T_end > checkpoint->state.ball.T))
    throw ConfigError(fmt::format("time.T_end = {:g}: must be later than the time of checkpoint "
                                  "'{}', T = {:.6g}",
                                  config.T_end, options.restart_file, checkpoint->state.ball.T),
                      "time.T_end");
  // Likewise a cap the checkpoint has reached (time.max_steps = 10 from step 85).
  const int done = checkpoint->state.step;
  if (!std::isfinite(config.T_end) && config.max_steps > 0 && config.max_steps <= done) {
    // The default cap was named as if the user had set it, with no way on.
    const bool by_default = config.max_steps == default_max_steps(config.Delta0, config.V0,
                                                                  effective_time_step(config));
    throw ConfigError(
        fmt::format("time.max_steps = {}{}: must be more than the steps of checkpoint "
                    "'{}', {}{}",
                    config.max_steps, by_default ? " (the default)" : "", options.restart_file,
                    done, by_default ? ": set a larger time.max_steps, or a time.T_end" : ""),
        "time.max_steps");
  }
  return kExitOk;
}

/// The one line of a run stopped by a signal between steps; its exit code.
int report_interrupted(const ImpactOptions& options, const KeptCheckpoint& kept,
                       const RunInterrupted& e) {
  const int signal = InterruptGuard::received();
  if (e.step == 0) {
    std::fprintf(stderr,
                 "ehlsim: interrupted by %s before the first step ended; nothing was written to "
                 "%s\n",
                 signal_name(signal).c_str(), cli::printable(options.out_dir).c_str());
  } else if (kept.step == 0 && !kept.spared.empty()) {
    std::fprintf(stderr,
                 "ehlsim: interrupted by %s after step %d (T = %.6g); no checkpoint was written "
                 "('%s', an earlier run's, was left as it was: output.checkpoint_every = 0): run "
                 "the command again\n",
                 signal_name(signal).c_str(), e.step, e.T,
                 cli::printable(kept.spared.string()).c_str());
  } else {
    std::fprintf(stderr, "ehlsim: interrupted by %s after step %d (T = %.6g); resume with: %s\n",
                 signal_name(signal).c_str(), e.step, e.T,
                 resume_command(options, kept.path).c_str());
  }
  return exit_code_for_signal(signal);
}

/// The one line of a failed run, with the resume line of its checkpoint; its exit code.
int report_failure(const ImpactOptions& options, const KeptCheckpoint& kept, const LastStep& last,
                   const std::exception& e) {
  // A failure of the solution names its step and repeats, bit for bit, from
  // the checkpoint unless a setting changes; one of the disk does neither.
  const bool repeats = dynamic_cast<const RunFailure*>(&e) != nullptr;
  std::string what = (repeats ? std::string() : last.where()) + cli::failure_reason(e);
  // A signal that came while the failing write was under way (a full disk)
  // did not end the run, but was sent: the line says it was seen.
  if (const int signal = InterruptGuard::received(); signal != 0)
    what += fmt::format(" ({} came meanwhile)", signal_name(signal));
  if (kept.step == 0) {
    print_error(what);
    return kExitFailure;
  }
  const std::string change =
      repeats ? fmt::format("with a change a restart allows ({}), ", kRestartMayChange) : "";
  print_error(fmt::format("{}; {}resume from the checkpoint of step {} with: {}", what, change,
                          kept.step, resume_command(options, kept.path)));
  return kExitFailure;
}

/// A run that writes checkpoints replaces one beside DIR that it does not
/// continue, an interrupted run's: said before it starts, with how to resume that one.
void warn_of_replaced_checkpoint(const ImpactOptions& options, const ImpactConfig& config,
                                 const std::filesystem::path& checkpoint) {
  std::error_code ec;
  if (config.checkpoint_every <= 0 || !std::filesystem::exists(checkpoint, ec)) return;
  if (resumes_from(options, checkpoint)) return;
  cli::print_warnings({fmt::format(
      "'{}', the checkpoint of an earlier run into '{}' that did not complete, will be replaced "
      "by this run's first checkpoint (to continue that run instead: --restart {})",
      cli::printable(checkpoint.string()), cli::printable(options.out_dir),
      shell_word(checkpoint.string()))});
}

/// A checkpoint of another build continues with other rounding: said before the run starts.
void warn_of_another_build(const ImpactOptions& options, const Checkpoint& checkpoint) {
  if (checkpoint.revision == source_revision()) return;
  cli::print_warnings({fmt::format(
      "checkpoint '{}' was written by revision {}, this ehlsim is revision {}: the steps from "
      "here on may differ in their last bits from those of an uninterrupted run",
      cli::printable(options.restart_file), cli::printable(checkpoint.revision),
      source_revision())});
}

int run_impact(const ImpactOptions& options) {
  // A signal during the set-up also ends the run cleanly, after its first step (main's guard).
  // Bad input throws ConfigError: exit 2 with its one line (main).
  const ImpactConfig config = load_config(cli::config_path(options.config_file), options.overrides);
  // Before anything big is allocated or the run directory is made.
  const MemoryBudget memory = check_run_memory(config, available_memory_mb());
  std::optional<Checkpoint> checkpoint;
  if (!options.restart_file.empty()) {
    const int code = read_restart_checkpoint(options, config, checkpoint);
    if (code != kExitOk) return code;
    warn_of_another_build(options, *checkpoint);
  }
  // Locks DIR, refuses a busy or foreign one (exit 2), before any output.
  std::optional<RunDirectory> run_dir(std::in_place, options.out_dir);
  run_dir->refuse_foreign_checkpoint();
  if (!options.quiet) {
    warn_of_replaced_checkpoint(options, config, run_dir->checkpoint());
    print_case(config, options.out_dir);
    if (checkpoint)
      print_out("  restart    from {} at step {}, T = {:.6g}\n", options.restart_file,
                checkpoint->state.step, checkpoint->state.ball.T);
  }
  const nlohmann::json invocation = impact_invocation_json(options, checkpoint, memory);
  // A restarted run that fails before its first checkpoint can be resumed
  // from the one it started from.
  KeptCheckpoint kept;
  if (checkpoint)
    kept = {checkpoint->state.step, options.restart_file, checkpoint->state.ball.T, {}};
  LastStep last =
      checkpoint ? LastStep(checkpoint->state.step, checkpoint->state.ball.T) : LastStep();
  try {
    simulate(options, config, checkpoint, *run_dir, invocation, kept, last);
  } catch (const RunInterrupted& e) {
    run_dir.reset();  // the partial files go; the checkpoint stays
    return report_interrupted(options, kept, e);
  } catch (const PublishInterrupted& e) {
    run_dir.reset();  // the staging directory goes; DIR is as it was
    return report_unpublished(options, config, kept, e.signal);
  } catch (const ConfigError&) {
    throw;
  } catch (const std::exception& e) {
    run_dir.reset();
    return report_failure(options, kept, last, e);
  }
  return kExitOk;
}

// ---------------------------------------------------------------------------
// ehlsim spike
// ---------------------------------------------------------------------------

struct SpikeOptions {
  std::string run_dir;
  std::string out_dir;  ///< "" = the run directory
  std::vector<std::string> overrides;
  bool quiet = false;
};

CLI::App* add_spike_command(CLI::App& app, SpikeOptions& options) {
  CLI::App* cmd = app.add_subcommand(
      "spike", "Spike analysis of every snapshot of a finished run (fields.nc, run.json).");
  cmd->add_option("run_dir", options.run_dir, "run directory of `ehlsim impact`")->required();
  cmd->add_option("-o,--out", options.out_dir,
                  "where to write spike_snapshots.csv, spike_profiles.csv and axis_profiles.csv "
                  "(default: the run directory)")
      ->check(cli::path_name("a directory"));
  cmd->add_option("--set", options.overrides,
                  "override a spike.* setting of the run, e.g. --set spike.filter=gaussian")
      ->type_name("KEY=VALUE")
      ->allow_extra_args(false)
      ->take_all();
  cli::add_quiet_flag(*cmd, options.quiet);
  return cmd;
}

int run_spike(const SpikeOptions& options) {
  const std::filesystem::path out = options.out_dir.empty() ? options.run_dir : options.out_dir;
  RunAnalysisReport report;
  const auto interrupted = [&out]() {
    const int signal = InterruptGuard::received();
    std::fprintf(stderr, "ehlsim: interrupted by %s: the spike files in '%s' were not changed\n",
                 signal_name(signal).c_str(), cli::printable(out.string()).c_str());
    return exit_code_for_signal(signal);
  };
  try {
    // A transaction on OUT, locked meanwhile (io/RunAnalysis.hpp).
    report = analyze_run_directory(options.run_dir, out, options.overrides);
  } catch (const RunInterrupted&) {
    return interrupted();
  } catch (const PublishInterrupted&) {
    return interrupted();
  }
  if (!options.quiet) {
    print_out("{} snapshots analysed; wrote", report.snapshots);
    for (const auto& file : report.files) print_out(" {}", file.string());
    print_out("\n");
    cli::print_warnings(report.warnings);
  }
  return kExitOk;
}

int run(int argc, char** argv) {
  CLI::App app{"ehlsim: lubricated ball impact on a flat (elastohydrodynamic lubrication)",
               "ehlsim"};
  app.set_version_flag("--version", program_text());
  app.require_subcommand(1);

  ImpactOptions impact;
  if (argc > 0) impact.program = argv[0];
  CLI::App* impact_cmd = add_impact_command(app, impact);
  SpikeOptions spike;
  CLI::App* spike_cmd = add_spike_command(app, spike);
  StudyOptions study;
  CLI::App* study_cmd = add_study_command(app, study);
  RollingOptions rolling;
  CLI::App* rolling_cmd = add_rolling_command(app, rolling);

  // CLI11 says only "A subcommand is required" for a misspelt one.
  const auto is_command = [&](const CLI::App* command) { return command->check_name(argv[1]); };
  if (argc > 1 && argv[1][0] != '-' && std::as_const(app).get_subcommands(is_command).empty()) {
    print_error(fmt::format("unknown command '{}' ({})", echo_input(argv[1]), cli::kCommandList));
    return kExitBadInput;
  }
  if (const std::string refused = cli::refused_option_form(app, argc, argv); !refused.empty()) {
    print_error(refused);
    return kExitBadInput;
  }
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    if (e.get_exit_code() == static_cast<int>(CLI::ExitCodes::Success)) {
      return app.exit(e);  // --help, --version
    }
    print_error(cli::parse_error_text(e, app, argc, argv));
    return kExitBadInput;
  }
  // Before the first parallel region, where libgomp makes the team.
  apply_user_thread_count();
  if (impact_cmd->parsed()) return run_impact(impact);
  if (spike_cmd->parsed()) return run_spike(spike);
  if (study_cmd->parsed()) return run_study(study);
  if (rolling_cmd->parsed()) return run_rolling(rolling);
  print_error("no command given (try ehlsim --help)");
  return kExitBadInput;
}

/// run() with every exception turned into its exit code and one line.
int run_reporting_errors(int argc, char** argv) {
  try {
    return run(argc, argv);
  } catch (const ehlsim::ConfigError& e) {
    // A signal that interrupted the reading of the input (a config file that
    // is a FIFO no one writes to) ends the command as a signal does, not as
    // bad input ("Interrupted system call", exit 2).
    if (const int signal = InterruptGuard::received(); signal != 0) {
      std::fprintf(stderr,
                   "ehlsim: interrupted by %s while the input was read (%s): nothing "
                   "was written\n",
                   signal_name(signal).c_str(), cli::printable(e.what()).c_str());
      return exit_code_for_signal(signal);
    }
    print_error(e.what());
    return kExitBadInput;
  } catch (const std::exception& e) {
    print_error(cli::failure_reason(e));
    return kExitFailure;
  } catch (...) {
    print_error("unknown failure");
    return kExitFailure;
  }
}

/// A case of `ehlsim study` (cli::kStudyPidVariable) gets SIGTERM when the
/// study ends: a case left running after `kill -9` of the study published
/// after it.  Set with the stop signals handled; a study that ended before
/// (this process has another parent then) is a SIGTERM at once.
void end_with_the_study() {
  const char* variable = std::getenv(cli::kStudyPidVariable);
  if (variable == nullptr) return;
  const std::string study = variable;
  unsetenv(cli::kStudyPidVariable);  // not for what this process starts
  prctl(PR_SET_PDEATHSIG, SIGTERM);
  if (std::to_string(getppid()) != study) std::raise(SIGTERM);
}

/// The command, with SIGINT, SIGTERM and SIGHUP as requests to stop that it
/// acts on (io/Interrupt.hpp) until it has ended, and ignored from then on:
/// the exit code then tells what the command left on disk, whenever a signal
/// comes.
int run_with_stop_signals(int argc, char** argv) {
  InterruptGuard interrupts;
  end_with_the_study();
  const int code = run_reporting_errors(argc, argv);
  interrupts.hold_until_exit();
  return code;
}

/// Opens /dev/null on whichever of stdin, stdout and stderr the caller closed
/// (`ehlsim impact >&- 2>&-`): else the first files ehlsim opens take those
/// descriptors, and the progress and error lines went into spike.csv.
void open_closed_standard_streams() {
  for (int fd = STDIN_FILENO; fd <= STDERR_FILENO; ++fd) {
    if (::fcntl(fd, F_GETFD) != -1 || errno != EBADF) continue;
    // open(2) returns the lowest free descriptor: this one.
    const int opened = ::open("/dev/null", fd == STDIN_FILENO ? O_RDONLY : O_WRONLY);
    if (opened != fd && opened >= 0) ::close(opened);
  }
}

}  // namespace

int main(int argc, char** argv) {
  open_closed_standard_streams();
  // ehlsim waits for its children (the cases of a study, the figure script,
  // the NetCDF children of io/IsolatedIo.hpp).  SIGCHLD ignored, as a
  // launcher may pass it on through exec, would have the kernel reap them
  // unseen: waitpid fails with ECHILD and their exit statuses are lost.
  std::signal(SIGCHLD, SIG_DFL);
  // What ehlsim makes is files; stdout only reports.  A reader of stdout that
  // goes away (`ehlsim study | head -3`) must not end a command (a study would
  // die at its next line, its cases left running): the write fails and is
  // dropped (cli::print_out), and the command runs to its end.
  std::signal(SIGPIPE, SIG_IGN);
  const int code = run_with_stop_signals(argc, argv);
  stop_here_for_tests("exit");  // with the signals ignored, the guard gone
  // HDF5's exit handler crashed (SIGSEGV) on a file whose nc_close had failed
  // (a full disk), when ehlsim wrote its NetCDF files itself.  They are written
  // in child processes now (io/IsolatedIo.hpp), so this process holds no file
  // being written; the exit handlers stay skipped after a failure as a guard
  // (every file is closed or removed by then), and the streams are flushed.
  if (code != kExitOk) {
    std::fflush(nullptr);
    std::_Exit(code);
  }
  return code;
}
