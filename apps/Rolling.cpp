#include "Rolling.hpp"

#include <fmt/format.h>

#include <chrono>
#include <cstdio>
#include <optional>
#include <string>

#include "Cli.hpp"
#include "config/Parameters.hpp"
#include "config/RollingParameters.hpp"
#include "impact/ImpactObserver.hpp"
#include "io/Interrupt.hpp"
#include "io/MemoryGuard.hpp"
#include "io/ProgressLine.hpp"
#include "io/RollingOutput.hpp"
#include "io/RunDirectory.hpp"
#include "rolling/FilmFormula.hpp"
#include "rolling/RollingProblem.hpp"

using namespace ehlsim;
using cli::print_out;

CLI::App* add_rolling_command(CLI::App& app, RollingOptions& options) {
  CLI::App* cmd = app.add_subcommand(
      "rolling", "Solve one steady rolling (or rolling and sliding) EHL point contact.");
  cli::add_case_options(*cmd, options, "a ball, M = 100, L = 10",
                        "fields.nc, the profiles and run.json");
  cli::add_quiet_flag(*cmd, options.quiet);
  cmd->footer("\n" + describe_parameters(rolling_parameters()));
  return cmd;
}

namespace {
void print_rolling_case(const RollingConfig& c, const std::string& out_dir) {
  print_out("ehlsim {} rolling -> {}\n", EHLSIM_VERSION, out_dir);
  print_out(
      "  case       M = {:.6g}, L = {:.6g}, D = {:.6g} (lambda_bar = {:.6g}, alpha_bar = "
      "{:.6g})\n",
      c.M, c.L, c.D, c.lambda_bar, c.alpha_bar);
  print_out("  lubricant  {}\n", lubricant_text(c.lubricant));
  print_out("  grid       {}^2 on X in [{:g}, {:g}], Y in [{:g}, {:g}]\n", c.grid_points, c.x_min,
            c.x_max, c.y_min, c.y_max);
  std::fflush(stdout);
}

/// The status line after one multigrid cycle.
std::string cycle_text(const RollingCycle& c, double elapsed, bool done) {
  const std::string retry = c.attempt > 0 ? fmt::format(" (retry at damping {:g})", c.damping) : "";
  return fmt::format("{}^2 cycle {}: residual {:.3e}, force error {:+.2e}, Hc {:.6g}{}  {}{}",
                     c.points, c.cycle, c.residual, c.force_error, c.Hc, retry,
                     done ? "done in " : "", format_duration(elapsed));
}

void print_rolling_summary(const RollingConfig& c, const RollingResult& r, double wall,
                           const std::string& out_dir) {
  const std::string fallback =
      r.fallback_after > 0
          ? fmt::format(" (after {} with the other deformation update)", r.fallback_after)
          : "";
  print_out(
      "Hc = {:.6g} ({:.5g} Moes; NVM formula {:.5g}), Hm = {:.6g} at X = {:.4g}, "
      "P_max = {:.5g}; {} cycles{}, {:.2f} s; output in {}\n",
      r.Hc, hertz_to_moes_film(r.Hc, c.M), r.Hc_moes_nvm, r.Hm, r.X_Hm, r.P_max, r.cycles, fallback,
      wall, out_dir);
  cli::print_warnings(r.warnings);
}
}  // namespace

int run_rolling(const RollingOptions& options) {
  // Bad input throws ConfigError: exit 2 with its one line (main).
  const RollingConfig config =
      load_rolling_config(cli::config_path(options.config_file), options.overrides);
  // Before anything big is allocated or the run directory is made.
  const MemoryBudget memory = check_run_memory(config, available_memory_mb());
  // Locks DIR, refuses a busy or foreign one (exit 2), before any output.
  RunDirectory run_dir(options.out_dir);
  if (!options.quiet) print_rolling_case(config, options.out_dir);
  const auto start = std::chrono::steady_clock::now();
  RollingResult result;
  StatusLine status(!options.quiet);
  try {
    RollingProblem problem(config);
    result = problem.run(
        [&](const RollingCycle& c) {
          if (InterruptGuard::received() != 0) throw RunInterrupted(c.cycle, 0.0);
          status.update([c](double elapsed, bool done) { return cycle_text(c, elapsed, done); });
        },
        [&](const std::string& line) { status.note(line); });
    status.finish();
  } catch (const RollingFailure& e) {
    cli::print_error(e.what());
    return cli::kExitFailure;
  } catch (const RunInterrupted&) {
    const int signal = InterruptGuard::received();
    std::fprintf(stderr, "ehlsim: interrupted by %s; nothing was written to %s\n",
                 signal_name(signal).c_str(), cli::printable(options.out_dir).c_str());
    return exit_code_for_signal(signal);
  }
  const double wall =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const nlohmann::json invocation = cli::invocation_json(options, memory_json(memory));
  write_rolling_run(run_dir.staging(), config, result, invocation, wall);
  try {
    run_dir.publish();
  } catch (const PublishInterrupted& e) {
    std::fprintf(stderr, "ehlsim: interrupted by %s; nothing was written to %s\n",
                 signal_name(e.signal).c_str(), cli::printable(options.out_dir).c_str());
    return exit_code_for_signal(e.signal);
  }
  if (!options.quiet) print_rolling_summary(config, result, wall, options.out_dir);
  return cli::kExitOk;
}
