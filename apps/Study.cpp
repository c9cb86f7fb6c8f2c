// ehlsim study: runs the paper's cases M = 10, 20, 50, 100 with L = 10 as
// child processes of this binary (`ehlsim impact`, one OpenMP thread each,
// --jobs at a time), and the steady rolling contact at M = 20 and 100
// (`ehlsim rolling`) for the paper's impact-rolling similarity, analyses the
// impacts' snapshots (`ehlsim spike`), writes the dry Hertz reference and
// draws the figures with scripts/plot_study.py.
//
//   <out>/M<M>/            the run of each case (timeseries.csv, spike.csv,
//                          fields.nc, run.json, spike_*.csv, axis_profiles.csv)
//   <out>/rolling_M<M>/    the rolling contact at the same M and L (profile_x.csv, ...)
//   <out>/logs/M<M>.log    the output of each child
//   <out>/dry.csv          T, A_dry of the dry Hertz impact (same Delta0, V0)
//   <out>/study.json       grid, cases, exit codes, wall times: written last; an
//                          earlier study's goes when the first case completes
//   <out>/figures/         fig1..fig6 and the histories, PNG + CSV: drawn into
//                          <out>/.figures.part-<pid>/, then swapped in whole
#include "Study.hpp"

#include <fcntl.h>
#include <fmt/format.h>
#include <fmt/ranges.h>
#include <signal.h>
#include <spawn.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <thread>
#include <variant>

#include "Cli.hpp"
#include "analysis/SpikeAnalysis.hpp"
#include "config/Parameters.hpp"
#include "config/RollingParameters.hpp"
#include "grid/Grid.hpp"
#include "io/AtomicFile.hpp"
#include "io/CsvWriter.hpp"
#include "io/Interrupt.hpp"
#include "io/MemoryGuard.hpp"
#include "io/ProgramInfo.hpp"
#include "io/RunAnalysis.hpp"
#include "io/RunDirectory.hpp"
#include "io/RunOutput.hpp"
#include "io/ThreadBudget.hpp"

extern char** environ;

namespace {

namespace fs = std::filesystem;
using namespace ehlsim;
using cli::kExitOk;
using cli::print_out;

/// The paper's cases (Lubrecht & Venner 2022, figure 5): M = 10, 20, 50, 100, L = 10.
constexpr double kStudyM[] = {100.0, 50.0, 20.0, 10.0};  // longest first
constexpr double kStudyL = 10.0;
/// The similarity figure (the paper's section 2): the steady rolling contact
/// at these M (same L, so the same lambda_bar as the impact), about 1 s each on 257^2.
constexpr double kRollingM[] = {20.0, 100.0};
/// The user's --set keys of these sections reach the rolling runs too (the
/// same lubricant and solids on both sides of the comparison); the impact's
/// solver, time and output keys mean nothing there.
constexpr std::string_view kSharedPhysicsSections[] = {"lubricant", "body"};
/// Times of the paper's figures 1-3: the first spike profile (3.223) and the
/// comparison of P(X) with P(R) (3.574).
constexpr double kFigureTimes[] = {3.223, 3.574};
/// Figures 3 and 4 (M = 100): profiles from T = 3.223 every 20 steps, and the
/// last ones before lift-off every 2 steps: snapshots every 2 steps from 3.223.
constexpr double kProfileCaseM = 100.0;
constexpr int kProfileSnapshotEvery = 2;
constexpr double kProfileSnapshotStart = 3.223;
/// Exit code reported for a child killed by signal s: 128 + s, as the shells do.
constexpr int kExitSignalBase = 128;
/// The child process image: this very binary.
constexpr const char* kSelf = "/proc/self/exe";

std::string case_name(double M) { return fmt::format("M{:g}", M); }
std::string rolling_case_name(double M) { return fmt::format("rolling_M{:g}", M); }

struct Case {
  std::string command = "impact";  ///< the ehlsim subcommand: impact or rolling
  std::string name;                ///< its directory and log: M20, rolling_M20
  double M = 0.0;
  std::vector<std::string> overrides;
  fs::path dir;
  fs::path log;
  pid_t pid = -1;
  bool signalled = false;  ///< the study's signal was passed on to it
  int exit_code = -1;
  double wall_seconds = 0.0;
  std::chrono::steady_clock::time_point start;
  std::vector<std::string> warnings;  ///< of its run.json, once it finished (exit 0)
};

std::vector<Case> study_cases(const StudyOptions& options, const fs::path& out) {
  std::vector<Case> cases;
  for (const double M : kStudyM) {
    Case c;
    c.M = M;
    c.name = case_name(M);
    c.dir = out / c.name;
    c.log = out / "logs" / (c.name + ".log");
    // The user's settings first; the study's own keys win.
    c.overrides = options.overrides;
    c.overrides.push_back(fmt::format("case.M={:g}", M));
    c.overrides.push_back(fmt::format("case.L={:g}", kStudyL));
    c.overrides.push_back(fmt::format("grid.points={}", options.grid));
    c.overrides.push_back(fmt::format("output.snapshot_times=[{}]", fmt::join(kFigureTimes, ", ")));
    if (M == kProfileCaseM) {
      c.overrides.push_back(fmt::format("output.snapshot_every={}", kProfileSnapshotEvery));
      c.overrides.push_back(fmt::format("output.snapshot_start={:g}", kProfileSnapshotStart));
    }
    cases.push_back(std::move(c));
  }
  return cases;
}

/// The key of a --set assignment, without the value and the blanks around it.
std::string override_key(const std::string& assignment) {
  std::string key = assignment.substr(0, assignment.find('='));
  key.erase(0, key.find_first_not_of(" \t"));
  key.erase(key.find_last_not_of(" \t") + 1);
  return key;
}

/// The rolling runs of the similarity figure, after the impacts (they take a second).
std::vector<Case> rolling_cases(const StudyOptions& options, const fs::path& out) {
  std::vector<Case> cases;
  for (const double M : kRollingM) {
    Case c;
    c.command = "rolling";
    c.M = M;
    c.name = rolling_case_name(M);
    c.dir = out / c.name;
    c.log = out / "logs" / (c.name + ".log");
    for (const std::string& o : options.overrides) {
      const std::string key = override_key(o);
      const std::string section = key.substr(0, key.find('.'));
      if (std::find(std::begin(kSharedPhysicsSections), std::end(kSharedPhysicsSections),
                    section) != std::end(kSharedPhysicsSections) &&
          rolling_parameters().find(key) != nullptr)
        c.overrides.push_back(o);
    }
    c.overrides.push_back(fmt::format("case.M={:g}", M));
    c.overrides.push_back(fmt::format("case.L={:g}", kStudyL));
    c.overrides.push_back(fmt::format("grid.points={}", options.rolling_grid));
    cases.push_back(std::move(c));
  }
  return cases;
}

/// "M = 20  " for an impact (the study's log lines), "rolling M = 20" for a rolling run.
std::string case_label(const Case& c) {
  return c.command == "impact" ? fmt::format("M = {:<4g}", c.M)
                               : fmt::format("rolling M = {:g}", c.M);
}

/// The environment with OMP_NUM_THREADS=1 (the study runs its cases side by side).
std::vector<std::string> child_environment() {
  std::vector<std::string> env;
  for (char** e = environ; *e != nullptr; ++e) {
    if (std::strncmp(*e, "OMP_NUM_THREADS=", std::strlen("OMP_NUM_THREADS=")) != 0)
      env.emplace_back(*e);
  }
  env.emplace_back("OMP_NUM_THREADS=1");
  return env;
}

std::vector<char*> c_strings(std::vector<std::string>& strings) {
  std::vector<char*> out;
  for (std::string& s : strings) out.push_back(s.data());
  out.push_back(nullptr);
  return out;
}

/// Starts the case `program args...` with stdout and stderr to `log`, told
/// the study's process id (cli::kStudyPidVariable); throws on failure.
pid_t spawn(const std::string& program, std::vector<std::string> args, const fs::path& log) {
  std::vector<std::string> env = child_environment();
  env.push_back(fmt::format("{}={}", cli::kStudyPidVariable, getpid()));
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, log.c_str(),
                                   O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_adddup2(&actions, STDOUT_FILENO, STDERR_FILENO);
  posix_spawn_file_actions_addopen(&actions, STDIN_FILENO, "/dev/null", O_RDONLY, 0);
  std::vector<char*> argv = c_strings(args);
  std::vector<char*> envp = c_strings(env);
  pid_t pid = -1;
  const int status =
      posix_spawn(&pid, program.c_str(), &actions, nullptr, argv.data(), envp.data());
  posix_spawn_file_actions_destroy(&actions);
  if (status != 0) {
    throw std::runtime_error(fmt::format("cannot start '{}': {}", program, std::strerror(status)));
  }
  return pid;
}

/// The signal the kernel sends the figure script's guardian when the study
/// dies (PR_SET_PDEATHSIG): one the study never forwards to the group.
constexpr int kStudyDiedSignal = SIGUSR2;

/// The signals the guardian waits for (and holds blocked), whose default
/// dispositions the script gets back.
constexpr std::array kGuardianSignals = {SIGINT, SIGTERM, SIGHUP, SIGCHLD, kStudyDiedSignal};

/// In a child that could not start the script: errno to `report`, then exit.
[[noreturn]] void report_start_failure(int report) {
  const int error = errno;
  (void)!write(report, &error, sizeof error);
  _exit(cli::kExitFailure);
}

/// A child's exit code, or kExitSignalBase + the signal that ended it.
int exit_code_of(int status) {
  if (WIFEXITED(status)) return WEXITSTATUS(status);
  return WIFSIGNALED(status) ? kExitSignalBase + WTERMSIG(status) : cli::kExitFailure;
}

/// In the script's process, a child of its guardian: the death signal, the
/// study's signal mask and default dispositions back, then the program.
/// Writes errno to `report` (close-on-exec) when the program cannot start.
[[noreturn]] void exec_script(const char* program, char** argv, char** envp, pid_t guardian,
                              const sigset_t& study_mask, int report) {
  prctl(PR_SET_PDEATHSIG, SIGKILL);
  if (getppid() != guardian) _exit(cli::kExitFailure);
  for (const int signal : kGuardianSignals) ::signal(signal, SIG_DFL);
  sigprocmask(SIG_SETMASK, &study_mask, nullptr);
  execve(program, argv, envp);
  report_start_failure(report);
}

/// In the child of spawn_group_leader, the leader of the script's process
/// group: the guardian.  It starts the script as its own child and waits for
/// it; when the study dies (even by SIGKILL, which the study cannot pass on)
/// the kernel tells it (PR_SET_PDEATHSIG), and it kills the whole group, so
/// that nothing the script started outlives the study.  The signals the study
/// forwards to the group reach the script; the guardian holds them blocked.
/// Only system calls (the study may have threads).
[[noreturn]] void become_group_leader(const char* program, char** argv, char** envp,
                                      const char* log, pid_t study, int report) {
  setpgid(0, 0);
  sigset_t study_mask;
  sigset_t waited;
  sigemptyset(&waited);
  for (const int signal : kGuardianSignals) sigaddset(&waited, signal);
  sigprocmask(SIG_BLOCK, &waited, &study_mask);
  prctl(PR_SET_PDEATHSIG, kStudyDiedSignal);
  if (getppid() != study) _exit(cli::kExitFailure);  // the study ended before prctl
  const int in = open("/dev/null", O_RDONLY);
  const int out = open(log, O_WRONLY | O_CREAT | O_TRUNC, 0644);
  if (in < 0 || out < 0 || dup2(in, STDIN_FILENO) < 0 || dup2(out, STDOUT_FILENO) < 0 ||
      dup2(out, STDERR_FILENO) < 0)
    report_start_failure(report);
  // A launcher's ignored SIGCHLD would reap the script unseen.
  ::signal(SIGCHLD, SIG_DFL);
  const pid_t guardian = getpid();
  const pid_t script = fork();
  if (script == 0) exec_script(program, argv, envp, guardian, study_mask, report);
  close(report);
  if (script < 0) _exit(cli::kExitFailure);
  for (;;) {
    siginfo_t info{};
    const int signal = sigwaitinfo(&waited, &info);
    if (signal == kStudyDiedSignal) kill(0, SIGKILL);  // the group, the guardian included
    int status = 0;
    if (signal == SIGCHLD && waitpid(script, &status, WNOHANG) == script)
      _exit(exit_code_of(status));  // the script's code, as the study reads it
  }
}

/// spawn for the figure script, in a process group of its own led by its
/// guardian (become_group_leader): the study signals the group, so that what
/// the script started ends with it (a `sleep` of the script outlived a study
/// stopped during the script), and the guardian kills the group when the
/// study is killed (a `kill -9` of the study alone left the script's own
/// children running).
pid_t spawn_group_leader(const std::string& program, std::vector<std::string> args,
                         const fs::path& log) {
  std::vector<std::string> env = child_environment();
  std::vector<char*> argv = c_strings(args);
  std::vector<char*> envp = c_strings(env);
  std::array<int, 2> report{};
  if (pipe2(report.data(), O_CLOEXEC) != 0)
    throw std::runtime_error(
        fmt::format("cannot start '{}': pipe: {}", program, std::strerror(errno)));
  const pid_t study = getpid();
  const pid_t pid = fork();
  if (pid == 0)
    become_group_leader(program.c_str(), argv.data(), envp.data(), log.c_str(), study, report[1]);
  close(report[1]);
  int error = 0;
  const ssize_t got = pid < 0 ? 0 : read(report[0], &error, sizeof error);  // 0: exec'd
  close(report[0]);
  if (pid < 0 || got == static_cast<ssize_t>(sizeof error)) {
    if (pid > 0) waitpid(pid, nullptr, 0);
    // A script whose "#!" line names a program that is not there fails as if
    // it were missing itself.
    std::error_code ec;
    const bool interpreter = pid > 0 && error == ENOENT && fs::exists(program, ec);
    throw std::runtime_error(
        fmt::format("cannot start '{}': {}{}", program, std::strerror(pid < 0 ? errno : error),
                    interpreter ? " (the interpreter its #! line names?)" : ""));
  }
  setpgid(pid, pid);  // also here, before the study may signal the group (EACCES once exec'd)
  return pid;
}

double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

/// The last line of a log (the child's error message).
std::string last_line(const fs::path& path) {
  std::ifstream in(path);
  std::string line;
  std::string last;
  while (std::getline(in, line)) {
    if (!line.empty()) last = line;
  }
  return last;
}

/// Why a child ended with `exit_code`, for the study's one line: its log's
/// last line, with control characters shown as '?' (a script's escape
/// sequences cleared the terminal), or how it ended when the log says nothing.
std::string failure_reason(const fs::path& log, int exit_code) {
  std::string reason = last_line(log);
  constexpr unsigned char kFirstPrintable = 0x20, kDelete = 0x7f;
  for (char& c : reason) {
    const auto byte = static_cast<unsigned char>(c);
    if (byte < kFirstPrintable || byte == kDelete) c = '?';
  }
  if (!reason.empty()) return reason;
  if (exit_code > kExitSignalBase) return "killed by " + signal_name(exit_code - kExitSignalBase);
  return "its log " + log.string() + " says nothing";
}

/// Passes the signal the study received on to its running children, once each.
void forward_signal(std::map<pid_t, Case*>& running) {
  const int signal = InterruptGuard::received();
  if (signal == 0) return;
  for (auto& [pid, c] : running) {
    if (!c->signalled) kill(pid, signal);
    c->signalled = true;
  }
}

/// How long a child that got the study's signal may take to end before it is
/// killed: a figure script that ignored SIGTERM kept the study waiting for as
/// long as it ran.
constexpr auto kSignalGrace = std::chrono::seconds(5);
/// How often the study looks whether a child has ended or a signal come:
/// short against kSignalGrace, long against a system call.  The study polls
/// rather than block in waitpid: a signal that came just before the call
/// (after the flag was looked at) did not end the wait, and a figure script
/// that ignored it kept the study waiting for ever.
constexpr auto kSignalPoll = std::chrono::milliseconds(50);

/// Waits for the group leader `pid` (spawn_group_leader), passing a signal
/// the study receives on to its group and killing the group kSignalGrace after
/// that if the leader has not ended; when it ends, what it left running in
/// its group is killed (a background child of the script wrote into the
/// figures' staging directory after the study had ended).
int wait_for_group(pid_t pid) {
  int status = 0;
  std::optional<std::chrono::steady_clock::time_point> signalled_at;
  for (;;) {
    siginfo_t ended{};
    const int waited = waitid(P_PID, static_cast<id_t>(pid), &ended, WEXITED | WNOWAIT | WNOHANG);
    if (waited == 0 && ended.si_pid == pid) {
      kill(-pid, SIGKILL);  // while the leader, not yet reaped, holds the group's id
      waitpid(pid, &status, 0);
      return exit_code_of(status);
    }
    if (waited < 0 && errno != EINTR)
      throw std::runtime_error(fmt::format("waitpid: {}", std::strerror(errno)));
    if (!signalled_at && InterruptGuard::received() != 0) {
      kill(-pid, InterruptGuard::received());
      signalled_at = std::chrono::steady_clock::now();
    } else if (signalled_at && std::chrono::steady_clock::now() - *signalled_at > kSignalGrace) {
      kill(-pid, SIGKILL);
    }
    std::this_thread::sleep_for(kSignalPoll);
  }
}

/// The warnings in the run.json of a finished case (none if it cannot be read).
std::vector<std::string> case_warnings(const Case& c) {
  try {
    const nlohmann::json run = read_run_json(c.dir / RunOutput::kRunFile);
    return run.at("results").value("warnings", std::vector<std::string>{});
  } catch (const std::exception&) {
    return {};
  }
}

/// Starts case `c` (its pid set); false, with the case failed and said so,
/// when it cannot be started.
bool start_case(Case& c) {
  // argv[0] the binary's path: the resume command in a case's log works as it is.
  std::vector<std::string> args = {fs::read_symlink(kSelf).string(), c.command, "--out",
                                   c.dir.string()};
  for (const std::string& o : c.overrides) {
    args.push_back("--set");
    args.push_back(o);
  }
  c.start = std::chrono::steady_clock::now();
  try {
    c.pid = spawn(kSelf, args, c.log);
  } catch (const std::runtime_error& e) {
    c.exit_code = cli::kExitFailure;
    print_out("  FAILED   {}: {}\n", case_label(c), e.what());
    return false;
  }
  print_out("  started  {} (pid {}, log {})\n", case_label(c), c.pid, c.log.string());
  std::fflush(stdout);
  return true;
}

/// Records and reports how case `c` ended (its wait status `status`).  The
/// first case that completes has replaced its run directory: `stale_summary`
/// (the study.json of an earlier study, which described the run replaced)
/// goes then, so that no summary stands beside runs it does not describe.
void report_ended(Case& c, int status, const fs::path& stale_summary) {
  c.exit_code = exit_code_of(status);
  c.wall_seconds = seconds_since(c.start);
  if (c.exit_code == kExitOk) {
    std::error_code ec;  // already gone after the first case
    fs::remove(stale_summary, ec);
    print_out("  finished {} in {:.1f} s\n", case_label(c), c.wall_seconds);
    c.warnings = case_warnings(c);
    for (const std::string& warning : c.warnings)
      print_out("  warning  {}: {}\n", case_label(c), warning);
  } else if (c.signalled && c.exit_code > kExitSignalBase) {
    print_out("  stopped  {} after {:.1f} s by {}\n", case_label(c), c.wall_seconds,
              signal_name(c.exit_code - kExitSignalBase));
  } else {
    print_out("  FAILED   {} after {:.1f} s (exit {}): {}\n", case_label(c), c.wall_seconds,
              c.exit_code, failure_reason(c.log, c.exit_code));
  }
  std::fflush(stdout);
}

/// Runs `cases`, `jobs` at a time (report_ended says what `stale_summary` is).
void run_cases(std::vector<Case>& cases, int jobs, const fs::path& stale_summary) {
  std::map<pid_t, Case*> running;
  std::size_t next = 0;
  bool waited_before = false;
  while (next < cases.size() || !running.empty()) {
    while (next < cases.size() && static_cast<int>(running.size()) < jobs &&
           InterruptGuard::received() == 0) {
      Case& c = cases[next++];
      if (start_case(c)) running[c.pid] = &c;  // else the others are still waited for
    }
    if (running.empty()) break;                        // interrupted before the next start
    forward_signal(running);                           // one that came while a case was starting
    if (!waited_before) stop_here_for_tests("cases");  // just before the first wait
    waited_before = true;
    int status = 0;
    const pid_t pid = waitpid(-1, &status, WNOHANG);
    if (pid == 0 || (pid < 0 && errno == EINTR)) {
      std::this_thread::sleep_for(kSignalPoll);
      continue;
    }
    if (pid < 0) throw std::runtime_error(fmt::format("waitpid: {}", std::strerror(errno)));
    const auto it = running.find(pid);
    if (it == running.end()) continue;
    Case& c = *it->second;
    running.erase(it);
    report_ended(c, status, stale_summary);
  }
}

void write_dry_reference(const fs::path& path, const ImpactConfig& config) {
  const DryContactRadius dry(config.Delta0, config.V0);
  const double dT = effective_time_step(config);
  CsvWriter csv(path, "T,A_dry");
  for (int k = 0;; ++k) {
    const double T = k * dT;
    if (T > dry.T_lift_off() + dT || (!std::isfinite(dry.T_lift_off()) && k > 0)) break;
    csv.append(fmt::format("{:.10g},{:.10g}", T, dry.at(T)));
  }
  csv.commit();
}

/// The one line of a study ended by a signal (no study.json is written); its
/// exit code.  `after_cases`: what the study was doing after its cases had run.
int report_interruption(const std::vector<Case>& cases, const std::string& after_cases = "") {
  std::vector<std::string> stopped;
  bool rolling_stopped = false;
  for (const Case& c : cases) {
    if (!c.signalled) continue;
    stopped.push_back(c.name);
    rolling_stopped = rolling_stopped || c.command == "rolling";
  }
  const int signal = InterruptGuard::received();
  std::fflush(stdout);
  if (!after_cases.empty()) {
    std::fprintf(stderr,
                 "ehlsim: interrupted by %s %s: the study stopped after its cases had run; no "
                 "study.json was written\n",
                 signal_name(signal).c_str(), after_cases.c_str());
    return exit_code_for_signal(signal);
  }
  std::fprintf(
      stderr, "ehlsim: interrupted by %s: the study stopped%s; no study.json was written\n",
      signal_name(signal).c_str(),
      stopped.empty()
          ? ""
          : fmt::format(" {} ({})", fmt::join(stopped, ", "),
                        rolling_stopped ? "a stopped impact's log says how to resume it; a "
                                          "rolling run is run again from its start"
                                        : "their logs say how to resume each")
                .c_str());
  return exit_code_for_signal(signal);
}

fs::path default_plot_script() { return fs::path(EHLSIM_SCRIPT_DIR) / "plot_study.py"; }

/// The keys the study sets in every case itself: a --set of one of them
/// would be overridden, so it is refused rather than ignored.
std::optional<std::string> study_owned(const std::string& key) {
  const std::string section = key.substr(0, key.find('.'));
  if (section == "case" || section == "physical")
    return fmt::format("M = {} with L = {:g}", fmt::join(kStudyM, ", "), kStudyL);
  // A Roelands law's own z or alpha would set an L of its own.
  if (key == "lubricant.z" || key == "lubricant.alpha")
    return fmt::format("the Roelands index from L = {:g}", kStudyL);
  if (key == "grid" || key == "grid.points") return std::string("grid.points from --grid");
  if (key == "output" || key.starts_with("output.snapshot_"))
    return std::string("the snapshots of the paper's figures");
  return std::nullopt;
}

/// Bad study options, before anything runs: exit 2 with the option named.
void check_grid_option(const char* option, int points, const char* what) {
  if (!(points >= kMinGridPoints && points <= kMaxGridPoints && is_power_of_two_plus_one(points))) {
    throw ConfigError(
        fmt::format("{} = {}: must be 2^k + 1 between {} and {} (the points per "
                    "side of {})",
                    option, points, kMinGridPoints, kMaxGridPoints, what));
  }
}

void check_study_options(const StudyOptions& options) {
  check_grid_option("--grid", options.grid, "every impact case");
  check_grid_option("--rolling-grid", options.rolling_grid, "the rolling runs");
  const int cores = available_cores();
  if (options.jobs < 1 || options.jobs > cores) {
    throw ConfigError(fmt::format(
        "--jobs = {}: must be in [1, {}] (the cores of this machine; each case runs on one)",
        options.jobs, cores));
  }
  for (const std::string& assignment : options.overrides) {
    const std::string key = override_key(assignment);
    // A key no case knows is bad input of its own: "unknown key", not "the study sets it".
    if (key.find('.') != std::string::npos && find_parameter(key) == nullptr)
      (void)load_config(std::nullopt, {assignment});
    if (const auto why = study_owned(key)) {
      throw ConfigError(fmt::format("--set '{}': the study sets {} itself in every case ({}); "
                                    "--set applies the other keys to every case",
                                    echo_input(assignment), echo_input(key), *why),
                        key);
    }
  }
  if (options.no_plots) return;
  std::error_code ec;
  const char* unusable = nullptr;
  if (::access(options.python.c_str(), X_OK) != 0) {
    unusable = std::strerror(errno);
  } else if (!fs::is_regular_file(options.python, ec)) {
    unusable = "not a regular file";  // a directory passes access(X_OK)
  }
  if (unusable != nullptr) {
    throw ConfigError(
        fmt::format("--python '{}': {} (give a Python 3 with numpy and matplotlib, or --no-plots)",
                    echo_input(options.python), unusable));
  }
}

/// What the figure script writes last into its directory.
constexpr std::string_view kFiguresSummary = "summary.json";

/// Copies into `staging` what `figures` holds that the new figures do not
/// replace (a file of the user's there was deleted with the earlier set);
/// copies, so that a swap that fails loses nothing.
void carry_over_other_files(const fs::path& figures, const fs::path& staging) {
  std::error_code ec;
  for (const fs::directory_entry& entry : fs::directory_iterator(figures, ec)) {
    const fs::path target = staging / entry.path().filename();
    if (fs::exists(fs::symlink_status(target))) continue;
    fs::copy(entry.path(), target, fs::copy_options::recursive | fs::copy_options::copy_symlinks);
  }
}

/// Runs the figure script (`python script STUDY_DIR FIGURES_DIR`) into a
/// staging directory beside `out`/figures and puts it in place when the
/// script succeeds (having written kFiguresSummary) and no signal came:
/// figures/ holds the earlier complete set or the new one, never a
/// half-drawn mix.  The script's exit code.
int draw_figures(const std::string& python, const fs::path& script, const fs::path& out,
                 const fs::path& log) {
  const fs::path figures = out / "figures";
  const std::string prefix = ehlsim::staging_prefix(figures.filename().string());
  std::error_code ec;
  for (const fs::directory_entry& entry : fs::directory_iterator(out, ec)) {
    // A killed study's (the study lock is ours).
    if (entry.path().filename().string().starts_with(prefix))
      ehlsim::remove_within_mount(entry.path());
  }
  const fs::path staging = out / fmt::format("{}{}", prefix, getpid());
  int code = cli::kExitFailure;
  try {
    fs::create_directory(staging);
    const pid_t pid =
        spawn_group_leader(python, {python, script.string(), out.string(), staging.string()}, log);
    stop_here_for_tests("figures");
    code = wait_for_group(pid);
    // The script's last act is summary.json: a script that exits 0 without
    // it drew nothing, and must not replace the earlier figures (--python
    // /bin/true left figures/ empty, with exit 0).
    if (code == kExitOk && !fs::is_regular_file(staging / kFiguresSummary, ec)) {
      std::ofstream(log, std::ios::app)
          << fmt::format("the figure script exited 0 without writing {}\n", kFiguresSummary);
      code = cli::kExitFailure;
    }
    if (code == kExitOk && InterruptGuard::received() == 0) {
      carry_over_other_files(figures, staging);
      replace_directory(staging, figures);
    }
  } catch (const std::runtime_error& e) {
    std::ofstream(log, std::ios::app) << e.what() << '\n';  // reported like a failed script
    code = cli::kExitFailure;
  }
  fs::remove_all(staging, ec);  // unless published
  return code;
}

/// The entry of a case in study.json; a finished impact's snapshots analysed first.
nlohmann::json case_summary(const Case& c) {
  nlohmann::json entry = {{"command", c.command},
                          {"M", c.M},
                          {"dir", c.dir.filename().string()},
                          {"exit_code", c.exit_code},
                          {"wall_seconds", c.wall_seconds}};
  if (c.exit_code == cli::kExitOk) entry["warnings"] = c.warnings;
  if (c.exit_code == cli::kExitOk && c.command == "impact") {
    const RunAnalysisReport report = analyze_run_directory(c.dir, c.dir, {});
    entry["snapshots"] = report.snapshots;
  }
  return entry;
}

/// The study's cases and what they share, every input checked before any
/// case starts (bad input: ConfigError).
struct StudyPlan {
  std::vector<Case> cases;  ///< the impacts, then the rolling contacts
  ImpactConfig reference;   ///< the impacts' case, for the dry reference
  fs::path script;          ///< the figure script
};

/// Each case checks its memory again when it starts; checked here, a case
/// that cannot fit ends the study before any case runs (ConfigError naming it).
template <class Config>
void check_case_memory(const Case& c, const Config& config) {
  try {
    (void)check_run_memory(config, available_memory_mb());
  } catch (const ConfigError& e) {
    throw ConfigError(fmt::format("case {}: {}", c.name, e.what()), e.key());
  }
}

StudyPlan plan_study(const StudyOptions& options) {
  check_study_options(options);
  const fs::path out = options.out_dir;
  StudyPlan plan{study_cases(options, out), {}, {}};
  // A study directory is no run directory: its cases' runs would stand
  // beside another run's results.
  if (std::error_code ec; fs::exists(out / RunOutput::kRunFile, ec)) {
    throw ConfigError(fmt::format("--out '{}' holds a run.json: it is a run directory, not a "
                                  "study's; choose another --out",
                                  out.string()),
                      "--out");
  }
  for (const Case& c : plan.cases) {
    plan.reference = load_config(std::nullopt, c.overrides);  // bad input: ConfigError
    check_case_memory(c, plan.reference);
  }
  for (Case& c : rolling_cases(options, out)) {
    check_case_memory(c, load_rolling_config(std::nullopt, c.overrides));
    plan.cases.push_back(std::move(c));
  }
  // Each case replaces its directory as a run does: one that holds files
  // ehlsim did not write is refused now, not when the case starts.
  for (const Case& c : plan.cases) {
    try {
      check_replaceable_run_directory(c.dir);
    } catch (const ConfigError& e) {
      throw ConfigError(fmt::format("case {}: {}", c.name, e.what()), e.key());
    }
  }
  // figures/ is replaced as a whole too.
  if (std::error_code ec; !options.no_plots && fs::is_directory(out / "figures", ec))
    check_no_mount_point(out / "figures");
  plan.script = options.plot_script.empty() ? default_plot_script() : fs::path(options.plot_script);
  if (std::error_code ec; !options.no_plots && !fs::is_regular_file(plan.script, ec)) {
    throw ConfigError(
        fmt::format("--plot-script '{}': {}", plan.script.string(),
                    fs::exists(plan.script, ec) ? "not a regular file" : "no such file"));
  }
  return plan;
}

/// The study.json entries of the cases (each finished impact's snapshots
/// analysed first), or the study's exit code when a signal stops an analysis.
std::variant<nlohmann::json, int> case_entries(const std::vector<Case>& cases) {
  nlohmann::json entries = nlohmann::json::array();
  for (const Case& c : cases) {
    // A signal stops the analysis before its swap: the case keeps its earlier spike files.
    const std::string analysis =
        fmt::format("during the spike analysis of {} (its spike files were not changed)", c.name);
    try {
      entries.push_back(case_summary(c));
    } catch (const RunInterrupted&) {
      return report_interruption(cases, analysis);
    } catch (const PublishInterrupted&) {
      return report_interruption(cases, analysis);
    } catch (const std::exception& e) {
      // A run the study made that cannot be analysed is a failure (exit 1),
      // not bad input (a ConfigError of the analysis ended the study with 2).
      throw std::runtime_error(
          fmt::format("the spike analysis of {} failed: {}", c.name, e.what()));
    }
  }
  return entries;
}

/// Draws the figures: their study.json entry, or the study's exit code when a
/// signal came during the script.
std::variant<nlohmann::json, int> figures_entry(const StudyOptions& options, const fs::path& script,
                                                const std::vector<Case>& cases) {
  const auto start = std::chrono::steady_clock::now();
  const fs::path out = options.out_dir;
  const fs::path log = out / "logs" / "plot.log";
  const int code = draw_figures(options.python, script, out, log);
  if (InterruptGuard::received() != 0) {
    return report_interruption(cases, "during the figure script (figures/ was not changed)");
  }
  if (code != cli::kExitOk) {
    print_out("  figure script failed (exit {}): {}\n", code, failure_reason(log, code));
  } else {
    print_out("  figures in {}\n", (out / "figures").string());
  }
  return nlohmann::json{
      {"script", script.string()}, {"exit_code", code}, {"wall_seconds", seconds_since(start)}};
}

}  // namespace

CLI::App* add_study_command(CLI::App& app, StudyOptions& options) {
  CLI::App* cmd = app.add_subcommand(
      "study",
      "The paper's spike study: M = 10, 20, 50, 100 (L = 10) in parallel, the dry "
      "reference, the spike analysis and the figures fig1..fig6; and the impact-rolling "
      "similarity: the rolling contact at M = 20, 100 beside the impact (figure similarity).");
  cmd->add_option("-g,--grid", options.grid,
                  "points per side of the impacts (2^k + 1; the paper used 1025)")
      ->transform(cli::decimal_integer())
      ->capture_default_str();
  cmd->add_option("--rolling-grid", options.rolling_grid,
                  "points per side of the rolling runs (2^k + 1; about 1 s each on 257)")
      ->transform(cli::decimal_integer())
      ->capture_default_str();
  cmd->add_option("-o,--out", options.out_dir, "study directory (created if missing)")
      ->check(cli::path_name("a directory"))
      ->capture_default_str();
  options.jobs = std::min(options.jobs, available_cores());
  cmd->add_option("-j,--jobs", options.jobs,
                  "cases run at the same time (one thread each), at most the number of cores")
      ->transform(cli::decimal_integer())
      ->capture_default_str();
  cmd->add_option(
         "--set", options.overrides,
         "passed to every case before the study's own keys, e.g. --set solver.max_cycles=30")
      ->type_name("KEY=VALUE")
      ->allow_extra_args(false)
      ->take_all();
  cmd->add_flag("--no-plots", options.no_plots, "skip the figure script");
  cmd->add_option("--python", options.python, "Python 3 with numpy and matplotlib")
      ->check(cli::path_name("a program"))
      ->capture_default_str();
  cmd->add_option("--plot-script", options.plot_script,
                  "figure script (default: " + default_plot_script().string() + ")")
      ->check(cli::path_name("a script"));
  return cmd;
}

int run_study(const StudyOptions& options) {
  // SIGINT, SIGTERM, SIGHUP (main's InterruptGuard) go on to the running cases; the study
  // waits for them.
  const auto start = std::chrono::steady_clock::now();
  StudyPlan plan = plan_study(options);
  const fs::path out = options.out_dir;
  if (std::error_code ec; (void)fs::status(out, ec), ec == std::errc::too_many_symbolic_link_levels)
    throw link_loop_error(out);
  // One study per directory: a second one would truncate the logs of the first.
  const PathLock lock(resolve_run_directory(refuse_non_directory(out)), out);
  (void)refuse_non_directory(out);  // again under the lock
  fs::create_directories(out / "logs");
  print_out("ehlsim study -> {}: M = {} (L = {:g}) on {}^2, rolling M = {} on {}^2, {} at a time\n",
            out.string(), fmt::join(kStudyM, ", "), kStudyL, options.grid,
            fmt::join(kRollingM, ", "), options.rolling_grid, options.jobs);
  std::fflush(stdout);
  run_cases(plan.cases, options.jobs, out / "study.json");
  if (InterruptGuard::received() != 0) return report_interruption(plan.cases);

  auto entries = case_entries(plan.cases);
  if (const int* code = std::get_if<int>(&entries)) return *code;
  nlohmann::json summary = {{"program", program_json("study")},
                            {"grid", options.grid},
                            {"rolling_grid", options.rolling_grid},
                            {"L", kStudyL},
                            {"overrides", options.overrides},
                            {"cases", std::move(std::get<nlohmann::json>(entries))}};
  bool ok =
      std::ranges::all_of(plan.cases, [](const Case& c) { return c.exit_code == cli::kExitOk; });
  write_dry_reference(out / "dry.csv", plan.reference);
  summary["runs_wall_seconds"] = seconds_since(start);

  if (!options.no_plots) {
    auto figures = figures_entry(options, plan.script, plan.cases);
    if (const int* code = std::get_if<int>(&figures)) return *code;
    summary["plots"] = std::move(std::get<nlohmann::json>(figures));
    ok = ok && summary["plots"]["exit_code"] == cli::kExitOk;
  }
  if (InterruptGuard::received() != 0) return report_interruption(plan.cases);
  summary["wall_seconds"] = seconds_since(start);
  write_json_atomic(out / "study.json", summary);
  print_out("study {} in {:.1f} s; summary in {}\n", ok ? "finished" : "FAILED",
            seconds_since(start), (out / "study.json").string());
  return ok ? cli::kExitOk : cli::kExitFailure;
}
