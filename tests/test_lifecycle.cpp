// The life of a run directory, end to end with the real binary (docs/usage.md,
// "What ehlsim guarantees about its outputs"): a re-run replaces the whole
// directory, foreign directories are refused, write errors and failures leave
// the earlier run intact, signals checkpoint and clean up, a restart from that
// checkpoint gives the uninterrupted run's bits, a busy directory is refused,
// a rolling run stopped by SIGTERM leaves nothing, a symbolic link --out stays
// one, `ehlsim study` passes a signal on to its cases and, signalled in its
// analyses or figure script, leaves no study.json and the earlier figures/,
// `ehlsim spike` replaces its three files in one swap, a signal before a swap
// (during an analysis, after the last step of a run) leaves DIR as it was, a
// signal after a command has ended changes nothing, and a reader of stdout
// that went away ends no command.  The test hook EHLSIM_TEST_STOP_AT stops the
// process at a chosen point, so that a test can look and signal there.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/mount.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <optional>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <tuple>
#include <utility>
#include <vector>

#include "io/Checkpoint.hpp"
#include "io/ProgramInfo.hpp"
#include "support/CheckpointDamage.hpp"
#include "support/MinimalRun.hpp"
#include "support/RunEhlsim.hpp"
#include "support/TempDir.hpp"
#include "support/TestPaths.hpp"

namespace {

namespace fs = std::filesystem;

using ehlsim::testing::ehlsim;
using ehlsim::testing::ehlsim_binary;
using ehlsim::testing::eio_shim;
using ehlsim::testing::library_crash;
using ehlsim::testing::quote;
using ehlsim::testing::read_file;
using ehlsim::testing::Result;
using ehlsim::testing::TempDir;
using ehlsim::testing::write_file;

/// A 33^2 rigid run of a few steps (well under a second).
const std::string kTiny = "--quiet --set grid.points=33 --set body.elastic=false ";
/// A 65^2 run of about 420 steps (2-4 s on one thread): long enough to be
/// signalled after its first step.
const std::vector<std::string> kLong = {"--set", "grid.points=65", "--set", "time.dT=0.01"};
constexpr auto kPoll = std::chrono::milliseconds(20);
constexpr auto kPatience = std::chrono::seconds(120);

Result run_into(const fs::path& dir, const std::string& options) {
  return ehlsim("impact " + kTiny + options + " --out " + quote(dir.string()));
}

/// The names in `dir`, sorted.
std::set<std::string> names_in(const fs::path& dir) {
  std::set<std::string> names;
  for (const auto& entry : fs::directory_iterator(dir)) names.insert(entry.path().filename());
  return names;
}

/// A child process of the binary, its stdout and stderr in files.
struct Child {
  pid_t pid = -1;
  fs::path out;
  fs::path err;
};

/// Environment variables set for a child: name, value.
using Environment = std::vector<std::pair<std::string, std::string>>;

/// The ehlsim binary and `args` as execv takes them.
class CommandLine {
 public:
  explicit CommandLine(const std::vector<std::string>& args) : strings_{ehlsim_binary()} {
    strings_.insert(strings_.end(), args.begin(), args.end());
    for (std::string& s : strings_) pointers_.push_back(s.data());
    pointers_.push_back(nullptr);
  }
  CommandLine(const CommandLine&) = delete;  // the pointers are into this one's strings
  CommandLine& operator=(const CommandLine&) = delete;
  [[nodiscard]] char* const* argv() const { return pointers_.data(); }

 private:
  std::vector<std::string> strings_;
  std::vector<char*> pointers_;
};

/// `stop_at`: the test hook EHLSIM_TEST_STOP_AT (docs/usage.md, "Test hooks").
Child start(const std::vector<std::string>& args, const fs::path& capture,
            const std::string& stop_at = "", const Environment& environment = {},
            bool own_process_group = false) {
  Child c{-1, capture.string() + ".out", capture.string() + ".err"};
  const CommandLine command(args);
  c.pid = fork();
  if (c.pid == 0) {
    if (own_process_group) setpgid(0, 0);  // as a shell starts a job
    const int out = open(c.out.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    const int err = open(c.err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    dup2(out, STDOUT_FILENO);
    dup2(err, STDERR_FILENO);
    if (!stop_at.empty()) setenv("EHLSIM_TEST_STOP_AT", stop_at.c_str(), 1);
    for (const auto& [name, value] : environment) setenv(name.c_str(), value.c_str(), 1);
    execv(command.argv()[0], command.argv());
    _exit(127);
  }
  return c;
}

/// Waits until `file` contains `text` (false after kPatience).
bool wait_for_text(const fs::path& file, const std::string& text) {
  const auto until = std::chrono::steady_clock::now() + kPatience;
  while (read_file(file).find(text) == std::string::npos) {
    if (std::chrono::steady_clock::now() > until) return false;
    std::this_thread::sleep_for(kPoll);
  }
  return true;
}

int exit_code_of(const Child& c) {
  int status = 0;
  waitpid(c.pid, &status, 0);
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

/// Waits until `c` has stopped itself at its EHLSIM_TEST_STOP_AT point (false
/// when it ended instead).
bool wait_until_stopped(const Child& c) {
  int status = 0;
  return waitpid(c.pid, &status, WUNTRACED) == c.pid && WIFSTOPPED(status);
}

/// How `c` ended: its exit code and what it printed.
Result result_of(const Child& c) {
  Result r;
  r.exit_code = exit_code_of(c);
  r.out = read_file(c.out);
  r.err = read_file(c.err);
  return r;
}

/// Sends `signal` (0: none) to the stopped `c`, lets it go on and returns how it ended.
Result resume(const Child& c, int signal) {
  if (signal != 0) kill(c.pid, signal);
  kill(c.pid, SIGCONT);
  return result_of(c);
}

/// Starts a long run into `dir`, waits for its first step, sends `signal`.
Result interrupted_run(const fs::path& dir, int signal, std::vector<std::string> extra = {}) {
  std::vector<std::string> args = {"impact", "--out", dir.string()};
  args.insert(args.end(), kLong.begin(), kLong.end());
  args.insert(args.end(), extra.begin(), extra.end());
  const Child c = start(args, dir.string() + "-capture");
  EXPECT_TRUE(wait_for_text(c.err, "step 1 "));
  kill(c.pid, signal);
  return result_of(c);
}

/// The last line of `text`.
std::string last_line(const std::string& text) {
  const std::size_t end = text.find_last_not_of('\n');
  const std::size_t start = text.rfind('\n', end);
  return text.substr(start == std::string::npos ? 0 : start + 1, end - start);
}

/// The siblings of `dir` that a run into it may leave: staging, old runs, lock.
std::vector<std::string> debris_beside(const fs::path& dir) {
  std::vector<std::string> debris;
  std::string hidden = ".";
  hidden.append(dir.filename().string()).append(".");
  for (const auto& entry : fs::directory_iterator(dir.parent_path())) {
    const std::string name = entry.path().filename();
    if (name.starts_with(hidden)) debris.push_back(name);
  }
  return debris;
}

TEST(Lifecycle, ARerunReplacesTheWholeDirectory) {
  TempDir work;
  const fs::path run = work / "run";
  ASSERT_EQ(run_into(run, "--set time.T_end=0.3 --set output.checkpoint_every=2").exit_code, 0);
  ASSERT_EQ(ehlsim("spike --quiet " + quote(run.string())).exit_code, 0);
  ASSERT_TRUE(fs::exists(run / "checkpoint.nc"));
  ASSERT_TRUE(fs::exists(run / "spike_snapshots.csv"));

  const Result r = run_into(run, "--set time.T_end=0.2");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  // Only the new run's files: no checkpoint.nc or spike_*.csv of the earlier one.
  EXPECT_EQ(names_in(run), (std::set<std::string>{"convergence.csv", "fields.nc", "run.json",
                                                  "spike.csv", "timeseries.csv"}));
  const auto json = nlohmann::json::parse(read_file(run / "run.json"));
  EXPECT_EQ(json["invocation"]["overrides"].back(), "time.T_end=0.2");
  EXPECT_EQ(names_in(work.path()), std::set<std::string>{"run"});  // no lock, staging, checkpoint
}

TEST(Lifecycle, ClosedStandardStreamsLeaveTheOutputsClean) {
  // With descriptors 0, 1 and 2 closed the first files opened took them, and
  // the progress line went into spike.csv ahead of its header (exit 0).
  TempDir work;
  const fs::path run = work / "run";
  const auto closed = [](const std::string& args) {
    const std::string command = quote(ehlsim_binary()) + " impact " + args + " <&- >&- 2>&-";
    const int status = std::system(command.c_str());
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  };
  ASSERT_EQ(closed("--set grid.points=33 --set time.T_end=0.3 --out " + quote(run.string())), 0);
  for (const std::string name : {"spike.csv", "timeseries.csv", "convergence.csv"}) {
    const std::string text = read_file(run / name);
    EXPECT_TRUE(text.starts_with("T,") || text.starts_with("step,")) << name << ": " << text;
  }
  EXPECT_EQ(nlohmann::json::parse(read_file(run / "run.json"))["results"]["outcome"], "t_end");
  EXPECT_EQ(closed("--set case.M=-1 --out " + quote((work / "bad").string())), 2);
}

TEST(Lifecycle, RefusesADirectoryItDidNotWrite) {
  TempDir work;
  const fs::path mine = work / "mine";
  fs::create_directories(mine);
  std::ofstream(mine / "notes.txt") << "keep me\n";
  Result r = run_into(mine, "");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.err, "ehlsim: error: --out '" + mine.string() +
                       "' is not empty and holds no ehlsim run.json: ehlsim writes only into a "
                       "new or empty directory or over an earlier ehlsim run; choose another "
                       "--out, or move the files yourself\n");
  EXPECT_EQ(read_file(mine / "notes.txt"), "keep me\n");

  // An earlier run with a file of the user's in it: refused, naming the file.
  const fs::path run = work / "run";
  ASSERT_EQ(run_into(run, "--set time.T_end=0.2").exit_code, 0);
  std::ofstream(run / "notes.txt") << "mine\n";
  r = run_into(run, "--set time.T_end=0.3");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("holds '" + (run / "notes.txt").string() + "', which ehlsim did not write"),
            std::string::npos)
      << r.err;
  EXPECT_EQ(read_file(run / "notes.txt"), "mine\n");
  fs::remove(run / "notes.txt");

  // A file of the user's that bears a run's name in a subdirectory is no
  // run's; a nested run and a spike analysis there are ehlsim's.
  fs::create_directories(run / "a" / "b");
  std::ofstream(run / "a" / "b" / "fields.nc") << "important\n";
  r = run_into(run, "--set time.T_end=0.3");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("holds '" + (run / "a" / "b" / "fields.nc").string() +
                       "', which ehlsim did not write"),
            std::string::npos)
      << r.err;
  EXPECT_EQ(read_file(run / "a" / "b" / "fields.nc"), "important\n");
  fs::remove_all(run / "a");
  ASSERT_EQ(run_into(run / "inner", "--set time.T_end=0.1").exit_code, 0);
  ASSERT_EQ(
      ehlsim("spike --quiet " + quote(run.string()) + " --out " + quote((run / "gauss").string()))
          .exit_code,
      0);
  EXPECT_EQ(run_into(run, "--set time.T_end=0.3").exit_code, 0);
  EXPECT_FALSE(fs::exists(run / "inner"));
  EXPECT_FALSE(fs::exists(run / "gauss"));

  const fs::path file = work / "file";
  std::ofstream(file) << "x";
  r = run_into(file, "");
  EXPECT_EQ(r.err, "ehlsim: error: --out '" + file.string() + "' exists and is not a directory\n");
  EXPECT_EQ(r.exit_code, 2);
}

TEST(Lifecycle, RefusesADirectoryTheUserMayNotWrite) {
  // A directory of mode 555 (the user's protection) was replaced by one of
  // 755.  Root may write anywhere, so as root the runs go as the user nobody.
  TempDir work;
  const fs::path place = work / "place";
  fs::create_directories(place);
  std::string launcher;
  // Debian's user and group nobody.
  constexpr uid_t kNobody = 65534;
  if (geteuid() == 0) {
    ASSERT_EQ(::chown(place.c_str(), kNobody, kNobody), 0) << std::strerror(errno);
    launcher = "setpriv --reuid=65534 --regid=65534 --clear-groups ";
    if (ehlsim("--version", launcher).exit_code != 0)
      GTEST_SKIP() << "the user nobody cannot run this build's ehlsim";
  }
  const fs::path writable = place / "writable";
  ASSERT_EQ(
      ehlsim("rolling --quiet --set grid.points=33 --out " + quote(writable.string()), launcher)
          .exit_code,
      0)
      << "the user's runs work where it may write";
  const fs::path locked = place / "locked";
  fs::create_directories(locked);
  if (geteuid() == 0) {
    ASSERT_EQ(::chown(locked.c_str(), kNobody, kNobody), 0);
  }
  fs::permissions(locked, fs::perms::owner_read | fs::perms::owner_exec | fs::perms::group_read |
                              fs::perms::group_exec | fs::perms::others_read |
                              fs::perms::others_exec);
  const std::string refusal = "ehlsim: error: --out '" + locked.string() +
                              "' is a directory this user may not write (Permission denied): "
                              "ehlsim replaces only a directory it may write; choose another "
                              "--out, or change the directory's mode\n";
  for (const std::string& command : std::vector<std::string>{
           "rolling --quiet --set grid.points=33", "impact " + kTiny + "--set time.T_end=0.2"}) {
    const Result r = ehlsim(command + " --out " + quote(locked.string()), launcher);
    EXPECT_EQ(r.exit_code, 2) << command;
    EXPECT_EQ(r.err, refusal) << command;
  }
  EXPECT_TRUE(fs::is_empty(locked));
  EXPECT_EQ(fs::status(locked).permissions() & fs::perms::owner_write, fs::perms::none);
  fs::permissions(locked, fs::perms::owner_all);  // for TempDir's removal
}

TEST(Lifecycle, ARunIntoASymbolicLinkLandsWhereItPoints) {
  TempDir work;
  const fs::path real = work / "real";
  fs::create_directories(real);
  fs::create_directory_symlink("real", work / "link");
  const std::set<std::string> run_files = {"convergence.csv", "fields.nc", "run.json", "spike.csv",
                                           "timeseries.csv"};
  for (const char* T_end : {"0.2", "0.3"}) {  // into the empty directory, then over that run
    const Result r = run_into(work / "link", std::string("--set time.T_end=") + T_end);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_TRUE(fs::is_symlink(work / "link")) << T_end;
    EXPECT_EQ(names_in(real), run_files) << T_end;
  }
  const auto json = nlohmann::json::parse(read_file(real / "run.json"));
  EXPECT_EQ(json["invocation"]["overrides"].back(), "time.T_end=0.3");
  // A dangling link gets its target, as a shell's `>` would.
  fs::create_directory_symlink("later", work / "pending");
  const Result r = run_into(work / "pending", "--set time.T_end=0.2");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(fs::is_symlink(work / "pending"));
  EXPECT_EQ(names_in(work / "later"), run_files);
  EXPECT_EQ(names_in(work.path()), (std::set<std::string>{"later", "link", "pending", "real"}));
}

/// The bytes of every file of a run directory.
std::vector<std::string> contents(const fs::path& dir) {
  std::vector<std::string> files;
  for (const std::string& name : names_in(dir)) files.push_back(name + read_file(dir / name));
  return files;
}

/// `ehlsim <args>` under `ulimit <limit>`: "-f KIB" (files beyond it fail
/// with EFBIG), "-n N" (no file descriptor from N on: EMFILE).  The streams
/// are redirected before the limit (dash moves a redirected file to a
/// descriptor of 10 or more first, which "-n 4" refuses), and descriptors
/// 3 to 9 that the test inherited are closed (ctest leaves one open): ehlsim
/// gets 0, 1 and 2 only, as from a shell.
Result with_ulimit(const std::string& limit, const std::string& args) {
  const TempDir capture("limit");
  const std::string command = "exec > " + quote((capture / "out").string()) + " 2> " +
                              quote((capture / "err").string()) +
                              " < /dev/null 3>&- 4>&- 5>&- 6>&- 7>&- 8>&- 9>&-; ulimit " + limit +
                              "; exec " + quote(ehlsim_binary()) + " " + args;
  const int status = std::system(("sh -c " + quote(command)).c_str());
  Result r;
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  r.out = read_file(capture / "out");
  r.err = read_file(capture / "err");
  return r;
}

/// A write that fails (ulimit -f: EFBIG, as a full disk gives ENOSPC) ends
/// with exit 1 and one line; the earlier run stays as it was.
TEST(Lifecycle, AWriteErrorLeavesTheEarlierRunIntact) {
  TempDir work;
  const fs::path run = work / "run";
  ASSERT_EQ(run_into(run, "--set time.T_end=0.3 --set output.checkpoint_every=2").exit_code, 0);
  const std::vector<std::string> before = contents(run);
  constexpr int kFileLimitKiB = 16;  // below the size of one 65^2 snapshot file
  const Result r =
      with_ulimit("-f " + std::to_string(kFileLimitKiB),
                  "impact --quiet --set grid.points=65 --set output.snapshot_every=1 --out " +
                      quote(run.string()));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_TRUE(r.err.starts_with("ehlsim: error: before the first time step: cannot write '"))
      << r.err;
  EXPECT_NE(r.err.find("File too large"), std::string::npos) << r.err;
  EXPECT_EQ(contents(run), before);
  EXPECT_EQ(names_in(work.path()), std::set<std::string>{"run"});
}

/// Out of file descriptors (ulimit -n), every command fails with exit 1 and
/// leaves no staging directory.  With 4 the lock holds the last descriptor:
/// the removal of the staging directory needed descriptors, and it stayed.
/// It is the machine's failure also where the input is read: `ehlsim spike`
/// said "not a complete ehlsim run directory" of run.json (exit 2), and the
/// pipe to the child that reads fields.nc or a checkpoint first (ulimit -n
/// 5) failed with exit 2 as if the file were bad.
TEST(Lifecycle, OutOfFileDescriptorsIsAFailureThatLeavesNothing) {
  TempDir work;
  const fs::path run = work / "run";
  ASSERT_EQ(run_into(run, "--set time.T_end=0.3 --set output.checkpoint_every=2").exit_code, 0);
  const std::vector<std::string> before = contents(run);
  const fs::path checkpoint = run / "checkpoint.nc";
  const std::vector<std::string> commands = {
      "spike --quiet " + quote(run.string()) + " --out " + quote((work / "spike").string()),
      "impact " + kTiny + "--out " + quote((work / "impact").string()),
      "impact " + kTiny + "--set time.T_end=0.5 --restart " + quote(checkpoint.string()) +
          " --out " + quote((work / "restart").string()),
      "rolling --quiet --set grid.points=33 --out " + quote((work / "rolling").string())};
  std::set<std::string> errors;
  for (const int limit : {4, 5, 6}) {
    for (const std::string& command : commands) {
      const Result r = with_ulimit("-n " + std::to_string(limit), command);
      EXPECT_EQ(r.exit_code, 1) << limit << " " << command << "\n" << r.err;
      EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
      EXPECT_NE(r.err.find(": Too many open files"), std::string::npos) << r.err;
      errors.insert(r.err);
    }
    EXPECT_EQ(names_in(work.path()), std::set<std::string>{"run"}) << limit;
  }
  EXPECT_EQ(contents(run), before);
  for (const std::string& input :
       {"'" + (run / "run.json").string() + "': ", "'" + (run / "fields.nc").string() + "': pipe: ",
        "checkpoint '" + checkpoint.string() + "': pipe: "}) {
    const std::string error = "ehlsim: error: cannot read " + input + "Too many open files\n";
    EXPECT_TRUE(errors.contains(error)) << error;
  }
}

/// A tmpfs of a few hundred kB (read-only with MS_RDONLY), unmounted at the
/// end (mount needs root).
class SmallTmpfs {
 public:
  explicit SmallTmpfs(const fs::path& at, unsigned long flags = 0, const std::string& size = "200k")
      : at_(at) {
    fs::create_directories(at_);
    mounted_ = mount("tmpfs", at_.c_str(), "tmpfs", flags, ("size=" + size).c_str()) == 0;
  }
  ~SmallTmpfs() {
    if (mounted_) umount(at_.c_str());
  }
  SmallTmpfs(const SmallTmpfs&) = delete;
  SmallTmpfs& operator=(const SmallTmpfs&) = delete;
  [[nodiscard]] bool mounted() const { return mounted_; }

 private:
  fs::path at_;
  bool mounted_ = false;
};

TEST(Lifecycle, ARunDirectoryWhereAFileSystemIsMountedIsNotReplaced) {
  // `ehlsim spike DIR` moved a tmpfs mounted at DIR/data along with the
  // earlier directory, then removed that and the files on the tmpfs, exit 0.
  TempDir work;
  const fs::path run = work / "run";
  ASSERT_EQ(run_into(run, "--set time.T_end=0.3").exit_code, 0);
  const SmallTmpfs data(run / "data");
  if (!data.mounted()) GTEST_SKIP() << "mount -t tmpfs is not permitted here";
  std::ofstream(run / "data" / "notes.txt") << "precious\n";
  const std::set<std::string> before = names_in(run);
  const Result r = ehlsim("spike " + quote(run.string()));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.err,
            "ehlsim: error: --out '" + run.string() + "' holds '" + (run / "data").string() +
                "', a mount point: ehlsim replaces the directory as a whole and cannot carry "
                "a mount over; unmount it, or choose another --out\n");
  EXPECT_EQ(read_file(run / "data" / "notes.txt"), "precious\n");
  EXPECT_EQ(names_in(run), before);
  EXPECT_EQ(names_in(work.path()), std::set<std::string>{"run"});  // no staging left
  // A file bind-mounted into DIR (the same file system: only statx tells).
  const fs::path other = work / "other";
  ASSERT_EQ(run_into(other, "--set time.T_end=0.3").exit_code, 0);
  std::ofstream(work / "mine.txt") << "mine\n";
  std::ofstream(other / "bound.txt") << "";
  ASSERT_EQ(
      mount((work / "mine.txt").c_str(), (other / "bound.txt").c_str(), nullptr, MS_BIND, nullptr),
      0);
  const Result bound = ehlsim("spike " + quote(other.string()) + " --out " + quote(other.string()));
  umount((other / "bound.txt").c_str());
  EXPECT_EQ(bound.exit_code, 2) << bound.err;
  EXPECT_NE(bound.err.find("holds '" + (other / "bound.txt").string() + "', a mount point"),
            std::string::npos)
      << bound.err;
  EXPECT_EQ(read_file(work / "mine.txt"), "mine\n");
}

TEST(Lifecycle, SpikeRefusesAnEntryItCannotCarryOverBeforeAnyWork) {
  // A FIFO in the directory: the whole analysis ran, and then the swap
  // failed with exit 1, "cannot carry '.../pipe' over".
  TempDir work;
  const fs::path run = work / "run";
  ASSERT_EQ(run_into(run, "--set time.T_end=0.3").exit_code, 0);
  for (const fs::path& fifo : {run / "pipe", run / "mine" / "pipe"}) {
    fs::create_directories(fifo.parent_path());
    ASSERT_EQ(::mkfifo(fifo.c_str(), 0644), 0) << std::strerror(errno);
    const std::set<std::string> before = names_in(run);
    // It never reaches the analysis, where the hook would stop it.
    const Child c = start({"spike", run.string()}, work / "spike", "analysis");
    int status = 0;
    ASSERT_EQ(waitpid(c.pid, &status, WUNTRACED), c.pid);
    if (WIFSTOPPED(status)) {
      kill(c.pid, SIGKILL);
      exit_code_of(c);
      FAIL() << "the analysis of " << fifo << " began";
    }
    EXPECT_EQ(WEXITSTATUS(status), 2) << fifo;
    EXPECT_EQ(read_file(c.err),
              "ehlsim: error: --out '" + run.string() + "' holds '" + fifo.string() +
                  "', a FIFO (named pipe): ehlsim makes the directory anew with links of "
                  "the entries it does not write, and can carry over only files, "
                  "directories and symbolic links; move it, or choose another --out\n");
    EXPECT_EQ(names_in(run), before);
    EXPECT_EQ(names_in(work.path()), (std::set<std::string>{"run", "spike.err", "spike.out"}));
    fs::remove(fifo);
  }
  EXPECT_EQ(ehlsim("spike --quiet " + quote(run.string())).exit_code, 0);
}

TEST(Lifecycle, AKilledRunsLeftoverKeepsWhatIsMountedInIt) {
  // The next run removes a killed run's staging directory (pid 999999 runs
  // no more), which emptied a tmpfs mounted in it: what is mounted stays.
  TempDir work;
  const fs::path debris = work / ".third.part-999999";
  const SmallTmpfs in_debris(debris / "data");
  if (!in_debris.mounted()) GTEST_SKIP() << "mount -t tmpfs is not permitted here";
  std::ofstream(debris / "data" / "notes.txt") << "precious\n";
  std::ofstream(debris / "fields.nc.part") << "debris";
  ASSERT_EQ(run_into(work / "third", "--set time.T_end=0.3").exit_code, 0);
  EXPECT_EQ(read_file(debris / "data" / "notes.txt"), "precious\n");
  EXPECT_FALSE(fs::exists(debris / "fields.nc.part"));  // the rest of the debris went
}

TEST(Lifecycle, AMountMadeDuringTheRunIsNeitherPublishedNorEmptied) {
  // One mounted in the staging directory was published into DIR; one mounted
  // in DIR was named by DIR's resolved path and not as --out gave it.
  TempDir work;
  fs::create_directory_symlink(work.path(), work / "via");
  const fs::path run = work / "run";
  const fs::path shown = work / "via" / "run";
  ASSERT_EQ(run_into(run, "--set time.T_end=0.2").exit_code, 0);
  const std::vector<std::string> before = contents(run);
  const std::vector<std::string> args = {
      "impact", "--quiet",        "--set", "grid.points=33", "--set", "body.elastic=false",
      "--set",  "time.T_end=0.3", "--out", shown.string()};
  const Child staged = start(args, work / "staged", "publish");
  ASSERT_TRUE(wait_until_stopped(staged));
  const fs::path staging = work / (".run.part-" + std::to_string(staged.pid));
  ASSERT_TRUE(fs::is_directory(staging));
  {
    const SmallTmpfs data(staging / "data");
    if (!data.mounted()) {
      resume(staged, SIGKILL);
      GTEST_SKIP() << "mount -t tmpfs is not permitted here";
    }
    std::ofstream(staging / "data" / "notes.txt") << "precious\n";
    const Result r = resume(staged, 0);
    EXPECT_EQ(r.exit_code, 1);
    EXPECT_NE(r.err.find("'" + (staging / "data").string() + "' was mounted during the run in '" +
                         staging.string() + "', where ehlsim writes the run before it replaces '" +
                         shown.string() + "': nothing was published; unmount it"),
              std::string::npos)
        << r.err;
    EXPECT_EQ(read_file(staging / "data" / "notes.txt"), "precious\n");
    EXPECT_EQ(contents(run), before);
  }
  fs::remove_all(staging);  // unmounted: the debris of the failed run
  // The staging directory itself mounted over: a bare "filesystem error:
  // cannot rename: Device or resource busy".
  const Child over = start(args, work / "over", "publish");
  ASSERT_TRUE(wait_until_stopped(over));
  const fs::path covered = work / (".run.part-" + std::to_string(over.pid));
  fs::create_directory(work / "empty");
  ASSERT_EQ(mount((work / "empty").c_str(), covered.c_str(), nullptr, MS_BIND, nullptr), 0);
  const Result r_over = resume(over, 0);
  umount(covered.c_str());
  EXPECT_EQ(r_over.exit_code, 1);
  EXPECT_NE(r_over.err.find("'" + covered.string() +
                            "', where ehlsim writes the run before it "
                            "replaces '" +
                            shown.string() +
                            "', was mounted over during the run: nothing was published; unmount it "
                            "(the next run into '" +
                            shown.string() + "' removes it)"),
            std::string::npos)
      << r_over.err;
  EXPECT_EQ(contents(run), before);
  ASSERT_EQ(run_into(run, "--set time.T_end=0.2").exit_code, 0);
  EXPECT_FALSE(fs::exists(covered));
  const Child in_dir = start(args, work / "in_dir", "publish");
  ASSERT_TRUE(wait_until_stopped(in_dir));
  const SmallTmpfs data(run / "data");
  const Result r = resume(in_dir, 0);
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("--out '" + shown.string() + "' holds '" + (shown / "data").string() +
                       "', a mount point"),
            std::string::npos)
      << r.err;
}

TEST(Lifecycle, ARunDirectoryThatIsAMountPointIsRefusedBeforeAnyWork) {
  // The swap failed with EBUSY after all the work.
  TempDir work;
  const SmallTmpfs mount_point(work / "mp");
  if (!mount_point.mounted()) GTEST_SKIP() << "mount -t tmpfs is not permitted here";
  const Result at_mount = run_into(work / "mp", "--set time.T_end=0.3");
  EXPECT_EQ(at_mount.exit_code, 2);
  EXPECT_EQ(at_mount.err, "ehlsim: error: --out '" + (work / "mp").string() +
                              "' is a mount point: ehlsim replaces the directory as a whole, "
                              "which a mount point cannot be; unmount it, or choose another "
                              "--out, such as a directory in it\n");
  // So is a study's case directory, before any case runs (all ran, then it failed).
  const Result study = ehlsim(
      "study --grid 33 --rolling-grid 33 --no-plots --set time.T_end=0.3 "
      "--out " +
      quote((work / "study").string()));
  ASSERT_EQ(study.exit_code, 0) << study.err;
  const SmallTmpfs case_mount(work / "study" / "M50");
  const Result refused = ehlsim(
      "study --grid 33 --rolling-grid 33 --no-plots --set "
      "time.T_end=0.3 --out " +
      quote((work / "study").string()));
  EXPECT_EQ(refused.exit_code, 2) << refused.out;
  EXPECT_NE(refused.err.find("case M50: --out '" + (work / "study" / "M50").string() +
                             "' is a mount point"),
            std::string::npos)
      << refused.err;
  EXPECT_EQ(refused.out.find("started"), std::string::npos) << refused.out;
  // A file bind-mounted where the run keeps its checkpoint: the first
  // checkpoint failed (EBUSY) after the steps before it.
  const fs::path checkpoint = work / "ck.checkpoint.nc";
  ASSERT_EQ(run_into(work / "src", "--set time.T_end=0.2").exit_code, 0);
  std::ofstream(checkpoint.string()) << "";
  ASSERT_EQ(
      mount((work / "src" / "fields.nc").c_str(), checkpoint.c_str(), nullptr, MS_BIND, nullptr),
      0);
  const Result bound =
      run_into(work / "ck", "--set time.T_end=0.3 --set output.checkpoint_every=1");
  umount(checkpoint.c_str());
  EXPECT_EQ(bound.exit_code, 2);
  EXPECT_EQ(bound.err, "ehlsim: error: --out '" + (work / "ck").string() +
                           "': a run keeps its checkpoint beside it, and '" + checkpoint.string() +
                           "' is a mount point: unmount it, or choose another --out\n");
}

TEST(Lifecycle, AFullDiskEndsWithOneLineAndNoCrash) {
  TempDir work;
  const SmallTmpfs disk(work / "disk");
  if (!disk.mounted()) GTEST_SKIP() << "mount -t tmpfs is not permitted here";
  const fs::path run = work / "disk" / "run";
  ASSERT_EQ(run_into(run, "--set time.T_end=0.3").exit_code, 0);
  const std::vector<std::string> before = contents(run);
  const Result r =
      ehlsim("impact --quiet --set grid.points=65 --set output.snapshot_every=1 --out " +
             quote(run.string()));
  EXPECT_EQ(r.exit_code, 1);  // not 139 (HDF5's exit handler)
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_NE(r.err.find("No space left on device"), std::string::npos) << r.err;
  EXPECT_EQ(contents(run), before);
  EXPECT_EQ(names_in(work / "disk"), std::set<std::string>{"run"});
  // Room for a checkpoint, not for its copy in the staging directory: it
  // said "Input/output error", with no resume line for the checkpoint left.
  const SmallTmpfs tight(work / "tight", 0, "120k");
  const fs::path d = work / "tight" / "d";
  const Result copy = ehlsim(
      "impact --quiet --set grid.points=33 --set time.dT=0.01 --set output.checkpoint_every=7 "
      "--out " +
      quote(d.string()));
  EXPECT_EQ(copy.exit_code, 1);
  EXPECT_NE(copy.err.find("after time step 7 (T = 0.07): cannot copy '"), std::string::npos)
      << copy.err;
  EXPECT_NE(copy.err.find("No space left on device; resume from the checkpoint of step 7 with: "),
            std::string::npos)
      << copy.err;
  EXPECT_EQ(names_in(work / "tight"), std::set<std::string>{"d.checkpoint.nc"});
}

/// A place no run can write into (issue 10: "permissions"): a read-only
/// tmpfs for root, whom file permissions do not stop, else a directory without
/// write permission.  Every command ends with exit 1 and one line naming the
/// path and the reason, and leaves nothing.
TEST(Lifecycle, AnUnwritablePlaceEndsWithOneLineNamingIt) {
  TempDir work;
  const fs::path place = work / "locked";
  std::optional<SmallTmpfs> read_only;
  std::string reason = "Permission denied";
  if (geteuid() == 0) {
    read_only.emplace(place, MS_RDONLY);
    if (!read_only->mounted()) GTEST_SKIP() << "mount -t tmpfs is not permitted here";
    reason = "Read-only file system";
  } else {
    fs::create_directories(place);
    fs::permissions(place, fs::perms::owner_read | fs::perms::owner_exec);
  }
  const std::string lock = "cannot create lock file '" + (place / ".run.lock").string() + "': ";
  const std::string parent = "cannot create '" + (place / "sub").string() +
                             "', the parent directory of --out '" +
                             (place / "sub" / "run").string() + "': ";
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"impact " + kTiny + "--set time.T_end=0.2 --out " + quote((place / "run").string()), lock},
      {"impact " + kTiny + "--out " + quote((place / "sub" / "run").string()), parent},
      {"rolling --quiet --set grid.points=33 --out " + quote((place / "run").string()), lock},
      {"study --grid 33 --no-plots --out " + quote((place / "run").string()), lock}};
  for (const auto& [args, message] : cases) {
    const Result r = ehlsim(args);
    EXPECT_EQ(r.exit_code, 1) << args;
    EXPECT_EQ(r.err, "ehlsim: error: " + message + reason + "\n") << args;
  }
  EXPECT_TRUE(fs::is_empty(place));
  if (!read_only) fs::permissions(place, fs::perms::owner_all);  // for TempDir's removal
}

/// Where and when the writes of a run fail with EIO (tests/support/eio_shim.cpp,
/// preloaded): no disk of a test machine can be made to give an I/O error.
struct InjectedEio {
  std::string file;       ///< a substring of the path of the files that fail
  long long after = 0;    ///< bytes those files take before the writes fail
  bool on_fsync = false;  ///< fsync fails instead of the writes
  /// Only the writes at this file offset count, one each (`after` of them
  /// succeed); empty: every byte counts.
  std::string offset = {};
  /// The reads that reach this file offset fail instead (the writes pass); empty: none.
  std::string read_at = {};
};

/// Starts ehlsim `args` with `eio` injected (tests/support/eio_shim.cpp preloaded).
Child start_with_eio(const std::vector<std::string>& args, const fs::path& capture,
                     const InjectedEio& eio) {
  // A sanitized ehlsim's ASan runtime refuses to start behind a preloaded
  // library unless told that this is expected.
  const char* asan = std::getenv("ASAN_OPTIONS");
  const std::string asan_options =
      (asan != nullptr && *asan != '\0' ? std::string(asan) + ":" : std::string()) +
      "verify_asan_link_order=0";
  return start(args, capture, "",
               {{"LD_PRELOAD", eio_shim()},
                {"EHLSIM_TEST_EIO_PATH", eio.file},
                {"EHLSIM_TEST_EIO_AFTER", std::to_string(eio.after)},
                {"EHLSIM_TEST_EIO_FSYNC", eio.on_fsync ? "1" : "0"},
                {"EHLSIM_TEST_EIO_OFFSET", eio.offset},
                {"EHLSIM_TEST_EIO_READ_AT", eio.read_at},
                {"ASAN_OPTIONS", asan_options}});
}

/// Offset 0 of a NetCDF-4 file: HDF5 writes its superblock there when it
/// creates or opens a file, when it ends the definitions, and twice when it
/// closes the file, the second time as its last write.
const std::string kSuperblock = "0";

/// A 33^2 elastic run of 80 steps (0.1 s) with a snapshot after each: its
/// timeseries.csv (10 kB) outgrows the 8 kB buffer of std::ofstream, so that
/// it is written during the run; its fields.nc takes 700 kB, its checkpoints
/// (output.checkpoint_every=20) 49 kB each.
const std::string kEioRun =
    "--quiet --set grid.points=33 --set time.dT=0.01 --set time.T_end=0.8 "
    "--set output.snapshot_every=1";

/// `ehlsim impact <kEioRun> <options> --out <run>` with `eio` injected.  Its
/// stderr has the pid in the staging directory's name replaced by "PID".
Result with_injected_eio(const fs::path& run, const std::string& options, const InjectedEio& eio) {
  std::vector<std::string> args = {"impact"};
  std::istringstream words(kEioRun + " " + options);
  for (std::string word; words >> word;) args.push_back(word);
  args.insert(args.end(), {"--out", run.string()});
  const TempDir capture("eio");
  const Child c = start_with_eio(args, capture / "impact", eio);
  Result r = result_of(c);
  const std::string pid = ".part-" + std::to_string(c.pid) + "/";
  for (std::size_t at = r.err.find(pid); at != std::string::npos; at = r.err.find(pid, at))
    r.err.replace(at, pid.size(), ".part-PID/");
  return r;
}

/// EIO injected by `eio` into a run with `options` over an earlier complete run
/// in a directory `tag`: exit 1 (no crash), one of `messages` (WORK stands for
/// that directory) as the one line on stderr, the earlier run byte for byte,
/// no staging directory, .part file or lock.
void expect_eio_case(const std::string& tag, const InjectedEio& eio, const std::string& options,
                     std::vector<std::string> messages) {
  const TempDir work(tag);
  const fs::path run = work / "run";
  ASSERT_EQ(run_into(run, "--set time.T_end=0.3 --set output.checkpoint_every=2").exit_code, 0);
  const std::vector<std::string> before = contents(run);
  const Result r = with_injected_eio(run, options, eio);
  EXPECT_EQ(r.exit_code, 1) << tag;  // not 128 + a signal
  for (std::string& message : messages)
    message.replace(message.find("WORK"), 4, work.path().string());
  EXPECT_NE(std::find(messages.begin(), messages.end(), r.err), messages.end())
      << tag << ": " << r.err << "expected: " << messages.front();
  EXPECT_EQ(contents(run), before) << tag;
  EXPECT_EQ(names_in(work.path()), std::set<std::string>{"run"}) << tag;
}

void expect_eio_case(const std::string& tag, const InjectedEio& eio, const std::string& options,
                     const std::string& message) {
  expect_eio_case(tag, eio, options, std::vector<std::string>{message});
}

TEST(Lifecycle, AnInputOnAFailingDiskIsTheMachinesFailureNotADamagedFile) {
  // HDF5 says "NetCDF: HDF error" of a read that failed with EIO, as of
  // damaged bytes: that was exit 2, bad input.  Now the file is read again,
  // and a disk that fails is the machine's failure: exit 1, saying so.
  const TempDir work("eio-read");
  const fs::path run = work / "run";
  ASSERT_EQ(ehlsim("impact " + kEioRun + " --out " + quote(run.string())).exit_code, 0);
  // A run that fails keeps its checkpoint: at step 40 (T = 3.75) of 42.
  const std::string checkpointed = "--quiet --set grid.points=33 --set output.checkpoint_every=20";
  ASSERT_EQ(ehlsim("impact " + checkpointed + " --set time.max_steps=42 --out " +
                   quote((work / "failed").string()))
                .exit_code,
            1);
  const fs::path checkpoint = work / "failed.checkpoint.nc";
  std::vector<std::string> restart = {"impact"};
  std::istringstream words(checkpointed + " --set time.T_end=3.8");
  for (std::string word; words >> word;) restart.push_back(word);
  restart.insert(restart.end(),
                 {"--restart", checkpoint.string(), "--out", (work / "again").string()});
  struct Case {
    std::vector<std::string> args;
    fs::path file;
  };
  const std::vector<Case> cases = {{{"spike", "--quiet", run.string()}, run / "fields.nc"},
                                   {restart, checkpoint}};
  for (const Case& c : cases) {
    const std::vector<std::string> before = contents(run);
    // From the middle of the file on, past its superblock and first metadata.
    const auto middle = std::to_string(fs::file_size(c.file) / 2);
    const Result r = result_of(
        start_with_eio(c.args, work / "capture", {.file = c.file.filename(), .read_at = middle}));
    EXPECT_EQ(r.exit_code, 1) << c.args.front();
    EXPECT_EQ(r.err, "ehlsim: error: cannot read '" + c.file.string() + "': Input/output error\n");
    EXPECT_EQ(contents(run), before);
    EXPECT_FALSE(fs::exists(work / "again"));
    // The same command on a sound disk reads the same file (the case's own check).
    EXPECT_EQ(result_of(start(c.args, work / "plain")).exit_code, 0) << c.args.front();
  }
}

TEST(Lifecycle, AnIOErrorInFieldsNcEndsWithOneLineNamingIt) {
  // The line names the last step the run completed, and the file.
  const std::string file = "cannot write 'WORK/.run.part-PID/fields.nc.part': ";
  // At once: HDF5 cannot create the file (NetCDF says EACCES; errno has the reason).
  expect_eio_case(
      "create", {"fields.nc", 0}, "",
      "ehlsim: error: before the first time step: " + file + "nc_create: Input/output error\n");
  // In the middle: each snapshot's child writes it when it closes the file
  // (the snapshots are held until the run ends: kFieldBatchBytes).
  const std::string at_the_end = "ehlsim: error: after time step 80 (T = 0.8): ";
  expect_eio_case("middle", {"fields.nc", 300'000}, "",
                  at_the_end + file + "nc_close (Input/output error): NetCDF: HDF error\n");
  // Everything written, the sync before the rename fails.
  expect_eio_case("fsync", {"fields.nc", 0, true}, "",
                  at_the_end +
                      "cannot sync 'WORK/.run.part-PID/fields.nc.part' to disk: Input/output "
                      "error\n");
}

TEST(Lifecycle, AnIOErrorInACsvFileEndsWithOneLineNamingIt) {
  const std::string message =
      "cannot write 'WORK/.run.part-PID/timeseries.csv.part': Input/output error\n";
  // The first 8 kB, during the run (CsvWriter::append).
  expect_eio_case("append", {"timeseries.csv", 0}, "",
                  "ehlsim: error: after time step 64 (T = 0.64): " + message);
  // The last 2 kB, flushed at the end (CsvWriter::commit).
  expect_eio_case("commit", {"timeseries.csv", 9000}, "",
                  "ehlsim: error: after time step 80 (T = 0.8): " + message);
}

TEST(Lifecycle, AnIOErrorInACheckpointEndsWithOneLineNamingIt) {
  const std::string file =
      "ehlsim: error: after time step 20 (T = 0.2): cannot write checkpoint "
      "'WORK/run.checkpoint.nc.part': ";
  const std::string options = "--set output.checkpoint_every=20";
  expect_eio_case("create", {"checkpoint.nc", 0}, options,
                  file + "nc_create: Input/output error\n");
  // In the middle of the first checkpoint (step 20).
  expect_eio_case("middle", {"checkpoint.nc", 30'000}, options,
                  file + "nc_close (Input/output error): NetCDF: HDF error\n");
  // The second checkpoint (step 40) fails: the first stays, to resume from.
  const TempDir work("second");
  const fs::path run = work / "run";
  ASSERT_EQ(run_into(run, "--set time.T_end=0.3 --set output.checkpoint_every=2").exit_code, 0);
  const std::vector<std::string> before = contents(run);
  // The first checkpoint of this run writes about 60 kB (five 33^2 fields),
  // and as much again for its copy in the staging directory.
  const Result r = with_injected_eio(run, options, {"checkpoint.nc", 150'000});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  const fs::path kept = work / "run.checkpoint.nc";
  EXPECT_TRUE(
      r.err.starts_with("ehlsim: error: after time step 40 (T = 0.4): cannot write checkpoint '" +
                        kept.string() + ".part': "))
      << r.err;
  EXPECT_NE(r.err.find("(Input/output error): NetCDF: HDF error; resume from the checkpoint of "
                       "step 20 with: "),
            std::string::npos)
      << r.err;
  EXPECT_NE(r.err.find("--restart " + kept.string()), std::string::npos) << r.err;
  EXPECT_EQ(ehlsim::read_checkpoint(kept).state.step, 20);
  EXPECT_EQ(contents(run), before);
  EXPECT_EQ(names_in(work.path()), (std::set<std::string>{"run", "run.checkpoint.nc"}));
}

/// HDF5 1.10.8 crashes (SIGSEGV in H5G_rootof, under NetCDF's report of the
/// objects left open) when the last write of nc_close fails.  ehlsim writes
/// its NetCDF files in child processes (io/IsolatedIo.hpp): the crash is one
/// line and exit 1, naming the file.  Under AddressSanitizer the child ends
/// with its report's exit status 1 instead of the signal.
TEST(Lifecycle, AFailedLastWriteOfANetcdfFileIsAnErrorNotACrash) {
  // `file` the start of the message: "checkpoint 'WORK/<partial file>"
  const auto crashed = [](const std::string& where, const std::string& file) {
    const std::string start = "ehlsim: error: " + where + "cannot write " + file +
                              "': the NetCDF/HDF5 library crashed writing it (";
    const std::string why =
        "; HDF5 1.10.8 does when the last write of a file fails, e.g. on an I/O error of the "
        "disk)\n";
    return std::vector<std::string>{start + "SIGSEGV" + why, start + "exit status 1" + why};
  };
  // The first checkpoint (step 20): its superblock writes are its creation,
  // nc_enddef and two at nc_close.
  expect_eio_case(
      "checkpoint", {"checkpoint.nc", 3, false, kSuperblock}, "--set output.checkpoint_every=20",
      crashed("after time step 20 (T = 0.2): ", "checkpoint 'WORK/run.checkpoint.nc.part"));
  // fields.nc: its creation, then the first snapshot (opened, written, closed).
  const std::string fields = "'WORK/.run.part-PID/fields.nc.part";
  expect_eio_case("fields-created", {"fields.nc", 3, false, kSuperblock}, "",
                  crashed("before the first time step: ", fields));
  expect_eio_case("fields-snapshot", {"fields.nc", 6, false, kSuperblock}, "",
                  crashed("after time step 80 (T = 0.8): ", fields));
}

/// A launcher may start ehlsim with SIGCHLD ignored (inherited through exec):
/// the kernel would then reap its children unseen, and the study's waitpid
/// failed with ECHILD (exit 1, a half-made study directory).  ehlsim restores
/// the default.
TEST(Lifecycle, SigchldIgnoredByTheLauncherDoesNotLoseTheChildren) {
  TempDir work;
  const fs::path out = work / "study";
  const fs::path err = work / "stderr";
  const std::string binary = ehlsim_binary();
  const pid_t pid = fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    // The launcher: SIGCHLD ignored, kept through exec.
    std::signal(SIGCHLD, SIG_IGN);
    const int null = open("/dev/null", O_RDWR);
    const int error = open(err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    dup2(null, STDIN_FILENO);
    dup2(null, STDOUT_FILENO);
    dup2(error, STDERR_FILENO);
    execl(binary.c_str(), binary.c_str(), "study", "--grid", "33", "--no-plots", "--out",
          out.c_str(), static_cast<char*>(nullptr));
    _exit(127);
  }
  int status = 0;
  ASSERT_EQ(waitpid(pid, &status, 0), pid);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 0) << read_file(err);
  EXPECT_TRUE(fs::exists(out / "study.json"));
}

/// A failed run keeps its last checkpoint (named in the message) and does not
/// touch the earlier run's checkpoint.nc.
TEST(Lifecycle, ARestartNamesTheBuildOfItsCheckpointAndWarnsOfAnother) {
  // Another build may round otherwise: a restart says so, and run.json names
  // the build of the checkpoint beside the build of the run.
  TempDir work;
  const fs::path run = work / "run";
  ASSERT_EQ(run_into(run, "--set output.checkpoint_every=2 --set time.max_steps=5").exit_code, 1);
  const fs::path kept = work / "run.checkpoint.nc";
  const std::string revision(ehlsim::source_revision());
  EXPECT_EQ(ehlsim::read_checkpoint(kept).revision, revision);
  // One of another build, and one of a build before revisions were recorded:
  // the checksum covers neither, and both still read.
  const fs::path other = work / "other.checkpoint.nc";
  fs::copy_file(kept, other);
  ehlsim::testing::rewrite_text_attribute(other, "ehlsim_revision", "0123456789ab");
  const fs::path legacy = work / "legacy.checkpoint.nc";
  fs::copy_file(kept, legacy);
  ehlsim::testing::delete_attribute(legacy, "ehlsim_revision");
  const std::vector<std::pair<fs::path, std::string>> cases = {
      {kept, revision}, {other, "0123456789ab"}, {legacy, "unknown"}};
  // No checkpoints of their own: no restart replaces another's file.
  const std::string restart = "--set output.checkpoint_every=0 --set time.T_end=0.5 --restart ";
  for (const auto& [checkpoint, written_by] : cases) {
    const Result r = run_into(run, restart + quote(checkpoint.string()));
    EXPECT_EQ(r.exit_code, 0) << r.err;
    const std::string warning =
        "ehlsim: warning: checkpoint '" + checkpoint.string() + "' was written by revision " +
        written_by + ", this ehlsim is revision " + revision +
        ": the steps from here on may differ in their last bits from those of an uninterrupted "
        "run\n";
    EXPECT_EQ(r.err, written_by == revision ? "" : warning) << checkpoint;
    const nlohmann::json json = nlohmann::json::parse(read_file(run / "run.json"));
    EXPECT_EQ(json.at("invocation").at("restart").at("revision"), written_by);
    EXPECT_EQ(json.at("program").at("revision"), revision);
  }
}

TEST(Lifecycle, AFailedRunKeepsItsCheckpointAndTheEarlierRun) {
  TempDir work;
  const fs::path run = work / "run";
  ASSERT_EQ(run_into(run, "--set time.T_end=0.3 --set output.checkpoint_every=2").exit_code, 0);
  const std::vector<std::string> before = contents(run);
  const Result r = run_into(run, "--set output.checkpoint_every=2 --set time.max_steps=5");
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_NE(r.err.find("no lift-off after 5 steps"), std::string::npos) << r.err;
  const fs::path kept = work / "run.checkpoint.nc";
  // The same command would fail the same way: the line says what may change.
  EXPECT_NE(r.err.find("; with a change a restart allows (solver.*, output.*, spike.*, time.T_end "
                       "and time.max_steps), resume from the checkpoint of step 4 with: "),
            std::string::npos)
      << r.err;
  EXPECT_NE(r.err.find("--restart " + kept.string()), std::string::npos) << r.err;
  EXPECT_EQ(ehlsim::read_checkpoint(kept).state.step, 4);
  EXPECT_EQ(contents(run), before);
  EXPECT_EQ(names_in(work.path()), (std::set<std::string>{"run", "run.checkpoint.nc"}));
  // Resumed without a change, the run fails again at step 5, before its
  // next checkpoint: the one it started from is still there, and named.
  const Result again = run_into(run,
                                "--set output.checkpoint_every=2 --set time.max_steps=5 "
                                "--restart " +
                                    quote(kept.string()));
  EXPECT_EQ(again.exit_code, 1);
  EXPECT_NE(again.err.find("no lift-off after 5 steps"), std::string::npos) << again.err;
  EXPECT_NE(again.err.find("resume from the checkpoint of step 4 with: "), std::string::npos)
      << again.err;
  EXPECT_NE(again.err.find("--restart " + kept.string()), std::string::npos) << again.err;
  EXPECT_EQ(ehlsim::read_checkpoint(kept).state.step, 4);
  EXPECT_EQ(contents(run), before);
  // With time.max_steps raised it goes on from there, to the new cap.
  const Result raised = run_into(run,
                                 "--set output.checkpoint_every=2 --set time.max_steps=7 "
                                 "--restart " +
                                     quote(kept.string()));
  EXPECT_NE(raised.err.find("no lift-off after 7 steps"), std::string::npos) << raised.err;
  EXPECT_NE(raised.err.find("resume from the checkpoint of step 6 with: "), std::string::npos)
      << raised.err;
}

TEST(Lifecycle, TheResumeCommandOfAConfigNamedLikeAnOptionWorks) {
  // `ehlsim impact -- -c.toml`: the resume command must not give "-c.toml"
  // where it is read as an option.
  TempDir work;
  write_file(work / "-c.toml", "[grid]\npoints = 33\n[body]\nelastic = false\n");
  const std::string in_work = "cd " + quote(work.path().string()) + " && ";
  const Result r = ehlsim(
      "impact --quiet --set output.checkpoint_every=2 --set time.max_steps=3 --out run -- -c.toml",
      in_work);
  ASSERT_EQ(r.exit_code, 1) << r.err;
  const std::string with = "resume from the checkpoint of step 2 with: ";
  const std::size_t at = r.err.find(with);
  ASSERT_NE(at, std::string::npos) << r.err;
  const std::string command = r.err.substr(at + with.size(), r.err.find('\n') - at - with.size());
  EXPECT_EQ(command, ehlsim_binary() +
                         " impact ./-c.toml --set output.checkpoint_every=2 --set "
                         "time.max_steps=3 --out run --restart run.checkpoint.nc --quiet");
  // As printed, with the cap raised: it goes on from step 2 to the new cap.
  const int status =
      std::system((in_work + command + " --set time.max_steps=5 2> resumed.err").c_str());
  EXPECT_EQ(WEXITSTATUS(status), 1);
  const std::string resumed = read_file(work / "resumed.err");
  EXPECT_NE(resumed.find("no lift-off after 5 steps"), std::string::npos) << resumed;
  EXPECT_NE(resumed.find("resume from the checkpoint of step 4 with: "), std::string::npos)
      << resumed;
}

/// The rows of timeseries.csv (without the header).
std::vector<std::string> rows(const fs::path& run) {
  std::vector<std::string> out;
  std::istringstream in(read_file(run / "timeseries.csv"));
  std::string line;
  std::getline(in, line);
  while (std::getline(in, line)) out.push_back(line);
  return out;
}

TEST(Lifecycle, ARunLeavesACheckpointBesideItsDirectoryThatItDidNotWrite) {
  // A run into DIR deleted DIR.checkpoint.nc when it completed, whatever it
  // was: an interrupted run's state, a file or a directory of the user's.
  TempDir work;
  const fs::path run = work / "run";
  const fs::path beside = work / "run.checkpoint.nc";
  ASSERT_EQ(
      run_into(work / "earlier", "--set time.T_end=0.3 --set output.checkpoint_every=2").exit_code,
      0);
  fs::copy_file(work / "earlier" / "checkpoint.nc", beside);
  ASSERT_EQ(run_into(run, "--set time.T_end=0.2").exit_code, 0);
  EXPECT_EQ(read_file(beside), read_file(work / "earlier" / "checkpoint.nc"));
  ASSERT_EQ(ehlsim("rolling --quiet --set grid.points=33 --out " + quote(run.string())).exit_code,
            0);
  EXPECT_TRUE(fs::exists(beside));
  // Nor does a run without checkpoints that a signal stops: the checkpoint of
  // its last step replaced the earlier run's without a word.
  const Result stopped = interrupted_run(run, SIGTERM);
  EXPECT_EQ(stopped.exit_code, 143);
  EXPECT_TRUE(std::regex_match(
      last_line(stopped.err),
      std::regex(
          "ehlsim: interrupted by SIGTERM after step [0-9]+ \\(T = [0-9.]+\\); no checkpoint "
          "was written \\('" +
          beside.string() +
          "', an earlier run's, was left as it was: output.checkpoint_every = 0\\): run "
          "the command again")))
      << stopped.err;
  EXPECT_EQ(read_file(beside), read_file(work / "earlier" / "checkpoint.nc"));
  // A run that writes checkpoints replaces it, and says so before it starts.
  const Result replacing = ehlsim(
      "impact --set grid.points=33 --set body.elastic=false --set time.T_end=0.2 --set "
      "output.checkpoint_every=2 --out " +
      quote(run.string()));
  ASSERT_EQ(replacing.exit_code, 0) << replacing.err;
  EXPECT_NE(replacing.err.find("ehlsim: warning: '" + beside.string() +
                               "', the checkpoint of an earlier run into '" + run.string() +
                               "' that did not complete, will be replaced by this run's first "
                               "checkpoint (to continue that run instead: --restart " +
                               beside.string() + ")"),
            std::string::npos)
      << replacing.err;
  fs::copy_file(work / "earlier" / "checkpoint.nc", beside, fs::copy_options::overwrite_existing);
  // Something else by that name is refused before the run: its checkpoint goes there.
  fs::remove(beside);
  write_file(beside, "my notes\n");
  const Result file = run_into(run, "--set time.T_end=0.2");
  EXPECT_EQ(file.exit_code, 2);
  EXPECT_EQ(file.err, "ehlsim: error: --out '" + run.string() +
                          "': a run keeps its checkpoint beside it, and cannot replace '" +
                          beside.string() +
                          "': not a NetCDF-4 file (ehlsim reads and writes NetCDF-4/HDF5 only; "
                          "the file does not start with the HDF5 signature): move it, or choose "
                          "another --out\n");
  EXPECT_EQ(read_file(beside), "my notes\n");
  fs::remove(beside);
  fs::create_directory(beside);
  EXPECT_EQ(run_into(run, "--set time.T_end=0.2").exit_code, 2);
  EXPECT_TRUE(fs::is_directory(beside));
  fs::remove(beside);
  // A dangling link was replaced by the run's checkpoint, then deleted.
  fs::create_symlink(work / "nothing", beside);
  const Result link = run_into(run, "--set time.T_end=0.2");
  EXPECT_EQ(link.exit_code, 2);
  EXPECT_NE(link.err.find("'" + beside.string() + "' is a symbolic link"), std::string::npos)
      << link.err;
  EXPECT_TRUE(fs::is_symlink(beside));
  fs::remove(beside);
  // ... and a file where the checkpoint is written before its rename.
  const fs::path partial = beside.string() + ".part";
  write_file(partial, "precious\n");
  EXPECT_EQ(run_into(run, "--set time.T_end=0.2").exit_code, 2);
  EXPECT_EQ(read_file(partial), "precious\n");
  fs::remove(partial);
  // Beside DIR as the run directory resolves: "nosuch/../run" wrote it
  // through a missing directory.
  const Result dotdot =
      ehlsim("impact " + kTiny + "--set time.T_end=0.2 --set " +
             "output.checkpoint_every=1 --out " + quote((work / "nosuch" / ".." / "run").string()));
  EXPECT_EQ(dotdot.exit_code, 0) << dotdot.err;
  EXPECT_TRUE(fs::exists(run / "checkpoint.nc"));
}

TEST(Lifecycle, APathIsResolvedAsTheKernelResolvesIt) {
  TempDir work;
  // runs -> data/runs, and runs/latest -> ../mine: the run replaced ./mine
  // (a lexical runs/../mine) and deleted the user's file there.
  fs::create_directories(work / "data" / "runs");
  fs::create_directories(work / "mine");
  write_file(work / "mine" / "thesis.txt", "precious\n");
  fs::create_directory_symlink("data/runs", work / "runs");
  ASSERT_EQ(run_into(work / "data" / "mine", "--set time.T_end=0.2").exit_code, 0);
  fs::create_directory_symlink("../mine", work / "data" / "runs" / "latest");
  ASSERT_EQ(run_into(work / "runs" / "latest", "--set time.T_end=0.3").exit_code, 0);
  EXPECT_EQ(read_file(work / "mine" / "thesis.txt"), "precious\n");
  EXPECT_EQ(names_in(work / "mine"), std::set<std::string>{"thesis.txt"});
  EXPECT_TRUE(fs::exists(work / "data" / "mine" / "run.json"));
  // "run/." put its checkpoint into run as ".checkpoint.nc", then refused run.
  const fs::path run = work / "run";
  ASSERT_EQ(run_into(run / ".", "--set time.T_end=0.2 --set output.checkpoint_every=1").exit_code,
            0);
  EXPECT_TRUE(fs::exists(run / "checkpoint.nc"));
  EXPECT_EQ(run_into(run, "--set time.T_end=0.2").exit_code, 0);
  // A file of the user's by the lock's name beside DIR was truncated and deleted.
  write_file(work / ".q.lock", "my notes\n");
  const Result lock = run_into(work / "q", "--set time.T_end=0.2");
  EXPECT_EQ(lock.exit_code, 2);
  EXPECT_NE(lock.err.find("' beside it is not an ehlsim lock"), std::string::npos) << lock.err;
  EXPECT_EQ(read_file(work / ".q.lock"), "my notes\n");
}

TEST(Lifecycle, ARunToTEndCheckpointsItsLastStepAndALaterTEndContinuesIt) {
  TempDir work;
  const fs::path whole = work / "whole";
  ASSERT_EQ(run_into(whole, "--set time.T_end=0.5").exit_code, 0);
  const fs::path part = work / "part";
  ASSERT_EQ(run_into(part, "--set time.T_end=0.3 --set output.checkpoint_every=4").exit_code, 0);
  const ehlsim::Checkpoint last = ehlsim::read_checkpoint(part / "checkpoint.nc");
  const std::vector<std::string> first = rows(part);
  EXPECT_EQ(last.state.step, static_cast<int>(first.size()));  // not a multiple of 4: the last
  const Result more =
      run_into(part, "--set time.T_end=0.5 --restart " + quote((part / "checkpoint.nc").string()) +
                         " --set output.checkpoint_every=4");
  ASSERT_EQ(more.exit_code, 0) << more.err;
  const std::vector<std::string> all = rows(whole);
  const std::vector<std::string> tail = rows(part);
  ASSERT_EQ(first.size() + tail.size(), all.size());
  EXPECT_TRUE(std::equal(tail.begin(), tail.end(), all.begin() + static_cast<long>(first.size())));
}

TEST(Lifecycle, SigintCheckpointsAndTheResumedRunHasTheSameBits) {
  TempDir work;
  const fs::path full = work / "full";
  const Result whole = ehlsim("impact --quiet --set grid.points=65 --set time.dT=0.01 --out " +
                              quote(full.string()));
  ASSERT_EQ(whole.exit_code, 0) << whole.err;

  const fs::path run = work / "run";
  const Result r = interrupted_run(run, SIGINT);
  ASSERT_EQ(r.exit_code, 130) << r.err;
  const std::string line = last_line(r.err);
  const std::regex message(
      "ehlsim: interrupted by SIGINT after step ([0-9]+) \\(T = [0-9.]+\\); resume with: (.*)");
  std::smatch match;
  ASSERT_TRUE(std::regex_match(line, match, message)) << line;
  const fs::path kept = work / "run.checkpoint.nc";
  EXPECT_EQ(match[2].str(), ehlsim_binary() +
                                " impact --set grid.points=65 --set time.dT=0.01 --out " +
                                run.string() + " --restart " + kept.string());
  EXPECT_EQ(ehlsim::read_checkpoint(kept).state.step, std::stoi(match[1].str()));
  // Nothing else: no run directory (there was none before), no staging, no lock.
  EXPECT_EQ(names_in(work.path()), (std::set<std::string>{"full", "run-capture.err",
                                                          "run-capture.out", "run.checkpoint.nc"}));

  // The resume command as printed, in a shell.
  const int status = std::system((match[2].str() + " --quiet > /dev/null").c_str());
  ASSERT_EQ(WEXITSTATUS(status), 0);
  const auto results = [](const fs::path& dir) {
    return nlohmann::json::parse(read_file(dir / "run.json"))["results"];
  };
  EXPECT_EQ(results(run), results(full));
  const std::vector<std::string> tail = rows(run);
  const std::vector<std::string> all = rows(full);
  ASSERT_EQ(tail.size() + std::stoul(match[1].str()), all.size());
  EXPECT_TRUE(std::equal(tail.begin(), tail.end(), all.end() - static_cast<long>(tail.size())));
  EXPECT_FALSE(fs::exists(kept));  // the completed run supersedes it
}

TEST(Lifecycle, AResumeLineOfADirectoryWithANewlineIsOneLineAndWorks) {
  // --out $'nl\nrun': the resume line spanned three lines of stderr.
  TempDir work;
  const fs::path run = work / "nl\nrun";
  const Result r = interrupted_run(run, SIGINT);
  ASSERT_EQ(r.exit_code, 130) << r.err;
  const std::string line = last_line(r.err);
  const std::string quoted = "$'" + work.path().string() + "/nl\\x0arun";
  EXPECT_NE(line.find("--out " + quoted + "' --restart " + quoted + ".checkpoint.nc'"),
            std::string::npos)
      << line;
  // bash reads the escape back: the printed command continues the run.
  const std::string command = line.substr(line.find("resume with: ") + 13);
  const int status = std::system(("bash -c " + quote(command + " --quiet")).c_str());
  EXPECT_EQ(WEXITSTATUS(status), 0);
  EXPECT_TRUE(fs::exists(run / "run.json"));
}

TEST(Lifecycle, SigtermAndSighupLeaveTheEarlierRunAndACheckpoint) {
  for (const auto& [signal, name, code] :
       {std::tuple{SIGTERM, "SIGTERM", 143}, std::tuple{SIGHUP, "SIGHUP", 129}}) {
    TempDir work(name);
    const fs::path run = work / "run";
    ASSERT_EQ(run_into(run, "--set time.T_end=0.3 --set output.checkpoint_every=2").exit_code, 0);
    const std::vector<std::string> before = contents(run);
    const Result r = interrupted_run(run, signal, {"--set", "output.checkpoint_every=50"});
    EXPECT_EQ(r.exit_code, code) << r.err;
    EXPECT_TRUE(last_line(r.err).starts_with(std::string("ehlsim: interrupted by ") + name +
                                             " after step "))
        << r.err;
    EXPECT_EQ(contents(run), before);
    EXPECT_EQ(
        names_in(work.path()),
        (std::set<std::string>{"run", "run-capture.err", "run-capture.out", "run.checkpoint.nc"}));
  }
}

TEST(Lifecycle, ASecondRunIntoABusyDirectoryExitsAtOnce) {
  TempDir work;
  const fs::path run = work / "run";
  std::vector<std::string> args = {"impact", "--out", run.string()};
  args.insert(args.end(), kLong.begin(), kLong.end());
  const Child first = start(args, work / "first");
  ASSERT_TRUE(wait_for_text(first.err, "step 1 "));
  const auto start_time = std::chrono::steady_clock::now();
  const Result second = run_into(run, "");
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start_time).count();
  EXPECT_EQ(second.exit_code, 2);
  EXPECT_TRUE(second.err.starts_with("ehlsim: error: --out '" + run.string() +
                                     "' is in use by another ehlsim run (pid " +
                                     std::to_string(first.pid) + " on host "))
      << second.err;
  EXPECT_LT(seconds, 10.0);  // at once, not after the first run
  // Nor does an analysis write there meanwhile.
  const Result spike = ehlsim("spike " + quote(run.string()));
  EXPECT_EQ(spike.exit_code, 2);
  EXPECT_NE(spike.err.find("is in use by another ehlsim run (pid " + std::to_string(first.pid)),
            std::string::npos)
      << spike.err;
  EXPECT_EQ(exit_code_of(first), 0) << read_file(first.err);  // undisturbed
  EXPECT_TRUE(fs::exists(run / "run.json"));

  // kill -9 leaves no lock that stops the next run, and its debris goes.
  const Child killed = start(args, work / "killed");
  ASSERT_TRUE(wait_for_text(killed.err, "step 1 "));
  kill(killed.pid, SIGKILL);
  EXPECT_EQ(exit_code_of(killed), 128 + SIGKILL);
  EXPECT_FALSE(debris_beside(run).empty());
  const Result after = run_into(run, "--set time.T_end=0.2");
  EXPECT_EQ(after.exit_code, 0) << after.err;
  EXPECT_TRUE(debris_beside(run).empty());
}

/// Waits until `path` exists (false after kPatience).
bool wait_for_path(const fs::path& path) {
  const auto until = std::chrono::steady_clock::now() + kPatience;
  while (!fs::exists(path)) {
    if (std::chrono::steady_clock::now() > until) return false;
    std::this_thread::sleep_for(kPoll);
  }
  return true;
}

TEST(Lifecycle, SigtermEndsARollingRunAndLeavesNothing) {
  TempDir work;
  const fs::path run = work / "run";
  // 513^2: 2.3 s unloaded on one thread, far longer than the signal takes to end it.
  const auto start_time = std::chrono::steady_clock::now();
  const Child c =
      start({"rolling", "--set", "grid.points=513", "--out", run.string()}, work / "rolling");
  // The staging directory exists once the run holds the lock on DIR.
  ASSERT_TRUE(wait_for_path(work / (".run.part-" + std::to_string(c.pid))));
  EXPECT_TRUE(fs::exists(work / ".run.lock"));
  kill(c.pid, SIGTERM);
  EXPECT_EQ(exit_code_of(c), 143);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start_time).count();
  EXPECT_EQ(last_line(read_file(c.err)),
            "ehlsim: interrupted by SIGTERM; nothing was written to " + run.string());
  // No run directory, no staging directory, no lock: only the captured output.
  EXPECT_EQ(names_in(work.path()), (std::set<std::string>{"rolling.err", "rolling.out"}));
  EXPECT_LT(seconds, 10.0);  // stopped after its first cycle, not at the end of the run
}

TEST(Lifecycle, ASignalEndsAStepThatWouldNeverEnd) {
  // A tolerance no iteration meets and cycles without a practical bound: the
  // solve at T = 0 cycles until round-off stops it, about 5 s on 513^2 (it
  // cycled for ever before it was stopped there).  A signal is acted on after
  // the cycle under way, not at the end of the solve.
  TempDir work;
  const fs::path run = work / "run";
  const auto start_time = std::chrono::steady_clock::now();
  const Child c = start({"impact", "--set", "grid.points=513", "--set", "solver.tolerance=1e-300",
                         "--set", "solver.max_cycles=2000000000", "--out", run.string()},
                        work / "endless");
  ASSERT_TRUE(wait_for_path(work / (".run.part-" + std::to_string(c.pid))));
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  kill(c.pid, SIGTERM);
  EXPECT_EQ(exit_code_of(c), 143);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start_time).count();
  // No step ended, so there is no state to continue from, and no resume line.
  EXPECT_EQ(last_line(read_file(c.err)),
            "ehlsim: interrupted by SIGTERM before the first step ended; nothing was written to " +
                run.string());
  EXPECT_EQ(names_in(work.path()), (std::set<std::string>{"endless.err", "endless.out"}));
  EXPECT_LT(seconds, 10.0);
}

TEST(Lifecycle, StudyPassesSigtermToItsCasesAndWritesNoSummary) {
  TempDir work;
  const fs::path study = work / "study";
  const Child c =
      start({"study", "--grid", "65", "--no-plots", "--jobs", "2", "--out", study.string()},
            work / "study");
  ASSERT_TRUE(wait_for_text(c.out, "started  M = 50"));
  // Both cases have done a step: their checkpoint is then of a step.
  ASSERT_TRUE(wait_for_text(study / "logs" / "M50.log", "step 1 "));
  ASSERT_TRUE(wait_for_text(study / "logs" / "M100.log", "step 1 "));
  kill(c.pid, SIGTERM);
  EXPECT_EQ(exit_code_of(c), 143);
  const std::string out = read_file(c.out);
  EXPECT_EQ(last_line(read_file(c.err)),
            "ehlsim: interrupted by SIGTERM: the study stopped M100, M50 (their logs say how to "
            "resume each); no study.json was written");
  EXPECT_FALSE(fs::exists(study / "study.json"));
  // The cases were waited for: they ended with the signal, each with its checkpoint.
  const std::regex started("pid ([0-9]+)");
  for (auto it = std::sregex_iterator(out.begin(), out.end(), started);
       it != std::sregex_iterator(); ++it) {
    EXPECT_FALSE(fs::exists(fs::path("/proc") / (*it)[1].str()))
        << "pid " << (*it)[1] << " runs on";
  }
  EXPECT_NE(out.find("stopped  M = 100"), std::string::npos) << out;
  EXPECT_NE(out.find(" s by SIGTERM\n"), std::string::npos) << out;
  EXPECT_EQ(out.find("FAILED"), std::string::npos) << out;
  EXPECT_NE(read_file(study / "logs" / "M100.log").find("resume with: "), std::string::npos);
  EXPECT_TRUE(fs::exists(study / "M100.checkpoint.nc"));
  EXPECT_TRUE(fs::exists(study / "M50.checkpoint.nc"));
}

/// A tiny study (33^2 impacts to T = 0.2, 65^2 rolling runs, no figures: a few seconds).
std::vector<std::string> tiny_study(const fs::path& out) {
  return {"study", "--grid",         "33",    "--rolling-grid", "65", "--no-plots",
          "--set", "time.T_end=0.2", "--out", out.string()};
}

/// tiny_study with figures drawn by the shell script `script` (a stand-in
/// for the figure script: no matplotlib needed).
std::vector<std::string> tiny_study_with_script(const fs::path& out, const fs::path& script) {
  std::vector<std::string> args = tiny_study(out);
  args.erase(std::find(args.begin(), args.end(), "--no-plots"));
  args.insert(args.end(), {"--python", "/bin/sh", "--plot-script", script.string()});
  return args;
}

/// Runs `args` with stdout a pipe that nobody reads any more (`ehlsim ... |
/// head -1` once head has ended) and stderr to `err`; its exit code.
int exit_code_with_stdout_unread(const std::vector<std::string>& args, const fs::path& err) {
  int ends[2];
  if (pipe(ends) != 0) return -1;
  const CommandLine command(args);
  const pid_t pid = fork();
  if (pid < 0) {
    close(ends[0]);
    close(ends[1]);
    return -1;
  }
  if (pid == 0) {
    const int error = open(err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    dup2(ends[1], STDOUT_FILENO);
    dup2(error, STDERR_FILENO);
    close(ends[0]);
    execv(command.argv()[0], command.argv());
    _exit(127);
  }
  close(ends[0]);  // the reader is gone before the first line
  close(ends[1]);
  return exit_code_of(Child{pid, "", err});
}

/// What ehlsim makes is files; stdout only reports.  A reader of stdout that
/// went away ended a command at its next line with SIGPIPE (exit 141): an
/// impact run after it had published, a study in the middle, its cases left
/// running.  Now each command runs to its end and says so by its exit code.
/// Starts a study of cases long enough to be killed (in a process group of
/// its own), kills it with SIGKILL (its whole group, or it alone) once both
/// cases run, and says whether a case still runs 20 s later.
bool a_case_outlives_a_killed_study(const fs::path& work, bool whole_group) {
  std::vector<std::string> args = tiny_study(work / "study");
  args.insert(args.end(), {"--set", "time.dT=1e-5"});  // cases of many seconds
  const Child c = start(args, work / "study", "", {}, true);
  EXPECT_TRUE(wait_for_text(c.out, "started  M = 50"));
  const std::string out = read_file(c.out);
  std::vector<std::string> cases;
  const std::regex started("pid ([0-9]+)");
  for (auto it = std::sregex_iterator(out.begin(), out.end(), started);
       it != std::sregex_iterator(); ++it)
    cases.push_back("/proc/" + (*it)[1].str());
  EXPECT_EQ(cases.size(), 2u) << out;
  kill(whole_group ? -c.pid : c.pid, SIGKILL);
  EXPECT_EQ(exit_code_of(c), 128 + SIGKILL);
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
  const auto any_runs = [&] {
    return std::any_of(cases.begin(), cases.end(),
                       [](const std::string& proc) { return fs::exists(proc); });
  };
  while (any_runs() && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(kPoll);
  return any_runs();
}

TEST(Lifecycle, AStudyKilledWithSigkillLeavesNoCaseRunning) {
  // `kill -9 -PGID` (as `timeout -s KILL` or a terminal's Ctrl-\ signal a
  // job) ended the study alone while each case led a process group of its
  // own, and the cases ran on and published after it.
  TempDir group;
  EXPECT_FALSE(a_case_outlives_a_killed_study(group.path(), true));
  // `kill -9` of the study alone: the cases get SIGTERM (PR_SET_PDEATHSIG)
  // and end as a signalled run does (a checkpoint and the resume line in its
  // log, or, before the first step, nothing written).
  TempDir alone;
  EXPECT_FALSE(a_case_outlives_a_killed_study(alone.path(), false));
  const std::string log = read_file(alone / "study" / "logs" / "M100.log");
  EXPECT_NE(log.find("ehlsim: interrupted by SIGTERM "), std::string::npos) << log;
}

TEST(Lifecycle, AReaderOfStdoutThatWentAwayEndsNoCommand) {
  TempDir work;
  const fs::path run = work / "run";
  EXPECT_EQ(exit_code_with_stdout_unread({"impact", "--set", "grid.points=33", "--set",
                                          "time.T_end=0.3", "--out", run.string()},
                                         work / "impact.err"),
            0)
      << read_file(work / "impact.err");
  EXPECT_TRUE(fs::exists(run / "run.json"));
  EXPECT_EQ(exit_code_with_stdout_unread({"spike", run.string()}, work / "spike.err"), 0)
      << read_file(work / "spike.err");
  EXPECT_TRUE(fs::exists(run / "spike_snapshots.csv"));
  const fs::path study = work / "study";
  EXPECT_EQ(exit_code_with_stdout_unread(tiny_study(study), work / "study.err"), 0)
      << read_file(work / "study.err");
  EXPECT_TRUE(fs::exists(study / "study.json"));
}

TEST(Lifecycle, ASignalDuringTheStudysAnalysesWritesNoSummary) {
  TempDir work;
  const fs::path study = work / "study";
  const Child earlier = start(tiny_study(study), work / "earlier");
  ASSERT_EQ(exit_code_of(earlier), 0) << read_file(earlier.err);
  ASSERT_TRUE(fs::exists(study / "study.json"));
  const std::set<std::string> complete = names_in(study);

  // Its cases have run (and replaced the earlier study's), the analysis of the
  // first one (M100) has done its first snapshot: SIGTERM.
  const Child c = start(tiny_study(study), work / "again", "analysis");
  ASSERT_TRUE(wait_until_stopped(c));
  const Result r = resume(c, SIGTERM);
  EXPECT_EQ(r.exit_code, 143) << r.out << r.err;
  EXPECT_EQ(
      r.err,
      "ehlsim: interrupted by SIGTERM during the spike analysis of M100 (its spike files were "
      "not changed): the study stopped after its cases had run; no study.json was written\n");
  // The earlier study.json described the runs the new cases replaced: it went
  // with the first of them, so no summary stands beside runs it does not describe.
  std::set<std::string> expected = complete;
  expected.erase("study.json");
  EXPECT_EQ(names_in(study), expected);  // no staging directory, lock or .part file
  // M100 is its new run, complete, without a half set of spike files.
  EXPECT_EQ(names_in(study / "M100"),
            (std::set<std::string>{"convergence.csv", "fields.nc", "run.json", "spike.csv",
                                   "timeseries.csv"}));
  // The cases not yet analysed are new complete runs too.
  EXPECT_TRUE(fs::exists(study / "M10" / "run.json"));
  EXPECT_FALSE(fs::exists(study / "M10" / "spike_snapshots.csv"));
}

TEST(Lifecycle, ASignalDuringTheFigureScriptLeavesTheEarlierFigures) {
  TempDir work;
  const fs::path study = work / "study";
  // A stand-in for the figure script (no matplotlib needed): it draws two
  // figures, or, once `slow` exists, one and then waits (exec: the signal the
  // study passes on reaches the waiting process itself).
  const fs::path script = work / "figures.sh";
  std::ofstream(script) << "if [ -e " << quote((work / "slow").string()) << " ]; then\n"
                        << "  echo new > \"$2/fig1.png\"; exec sleep 60\n"
                        << "fi\n"
                        << "echo earlier > \"$2/fig1.png\"; echo earlier > \"$2/fig2.png\"\n"
                        << "echo '{}' > \"$2/summary.json\"\n";
  const std::vector<std::string> args = tiny_study_with_script(study, script);
  const Child earlier = start(args, work / "earlier");
  ASSERT_EQ(exit_code_of(earlier), 0) << read_file(earlier.out) << read_file(earlier.err);
  ASSERT_EQ(names_in(study / "figures"),
            (std::set<std::string>{"fig1.png", "fig2.png", "summary.json"}));

  std::ofstream(work / "slow") << "";
  const Child c = start(args, work / "again");
  ASSERT_TRUE(wait_for_path(study / (".figures.part-" + std::to_string(c.pid)) / "fig1.png"));
  kill(c.pid, SIGTERM);
  const Result r = result_of(c);
  EXPECT_EQ(r.exit_code, 143) << r.out << r.err;
  EXPECT_EQ(r.err,
            "ehlsim: interrupted by SIGTERM during the figure script (figures/ was not changed): "
            "the study stopped after its cases had run; no study.json was written\n");
  EXPECT_EQ(read_file(study / "figures" / "fig1.png"), "earlier\n");  // the earlier set, whole
  EXPECT_EQ(read_file(study / "figures" / "fig2.png"), "earlier\n");
  EXPECT_EQ(names_in(study),
            (std::set<std::string>{"M10", "M100", "M20", "M50", "dry.csv", "figures", "logs",
                                   "rolling_M100", "rolling_M20"}));  // no staging, no summary

  // A script that exits 0 without its summary.json drew nothing: the study
  // fails, and the earlier figures stay (`--python /bin/true` left figures/ empty, exit 0).
  std::ofstream(script, std::ios::trunc) << "echo half > \"$2/fig1.png\"\n";
  const Result empty = result_of(start(args, work / "empty"));
  EXPECT_EQ(empty.exit_code, 1) << empty.out << empty.err;
  EXPECT_NE(empty.out.find("figure script failed (exit 1): the figure script exited 0 without "
                           "writing summary.json"),
            std::string::npos)
      << empty.out;
  EXPECT_EQ(read_file(study / "figures" / "fig1.png"), "earlier\n");
  EXPECT_EQ(names_in(study / "figures"),
            (std::set<std::string>{"fig1.png", "fig2.png", "summary.json"}));
}

/// How a study ended after SIGTERM: what it said, and the seconds it took.
struct Ended {
  Result result;
  double seconds = 0.0;
};

/// Sends SIGTERM to `c` (and SIGCONT when it is `stopped` at a hook); how it ended.
Ended ended_by_sigterm(const Child& c, bool stopped) {
  const auto signalled = std::chrono::steady_clock::now();
  Result r = stopped ? resume(c, SIGTERM) : (kill(c.pid, SIGTERM), result_of(c));
  return {std::move(r),
          std::chrono::duration<double>(std::chrono::steady_clock::now() - signalled).count()};
}

/// A study whose figure script ignores SIGTERM gets SIGTERM: once the script
/// drew its first figure, or (`at_hook`) while the study is stopped at the
/// hook `figures`, before its first wait.  It ends within the grace of 5 s,
/// then SIGKILL, and writes no figures.
void expect_ignoring_script_killed(bool at_hook) {
  TempDir work;
  const fs::path study = work / "study";
  const fs::path script = work / "figures.sh";
  std::ofstream(script) << "trap '' TERM INT HUP\n"
                        << "echo new > \"$2/fig1.png\"\n"
                        << "while :; do sleep 1; done\n";
  const std::vector<std::string> args = tiny_study_with_script(study, script);
  const Child c = start(args, work / "study", at_hook ? "figures" : "");
  if (at_hook) {
    ASSERT_TRUE(wait_until_stopped(c));
  } else {
    ASSERT_TRUE(wait_for_path(study / (".figures.part-" + std::to_string(c.pid)) / "fig1.png"));
  }
  const auto [r, seconds] = ended_by_sigterm(c, at_hook);
  EXPECT_EQ(r.exit_code, 143) << r.out << r.err;
  EXPECT_LT(seconds, 30.0);  // the grace of 5 s, then SIGKILL
  EXPECT_FALSE(fs::exists(study / "figures"));
}

TEST(Lifecycle, AFigureScriptThatIgnoresTheSignalIsKilled) {
  // It kept the study waiting for as long as it ran.
  expect_ignoring_script_killed(false);
}

TEST(Lifecycle, ASignalJustBeforeTheStudyWaitsForItsScriptEndsIt) {
  // The study looks at its signal between polls, never blocked in waitid
  // (the race of the next test, for the cases); here the old code passed too.
  expect_ignoring_script_killed(true);
}

TEST(Lifecycle, ASignalJustBeforeTheStudyWaitsForItsCasesStopsThem) {
  // The study blocked in waitpid and passed a signal on to its cases when the
  // call returned: one that came just before the call (here: while the study
  // is stopped at the hook) waited for the first case to end by itself, 76 s
  // here (on 1025^2 many minutes).  The cases run to T = 4 on 513^2.
  TempDir work;
  const fs::path study = work / "study";
  std::vector<std::string> args = tiny_study(study);
  *std::find(args.begin(), args.end(), "33") = "513";
  *std::find(args.begin(), args.end(), "time.T_end=0.2") = "time.T_end=4";
  const Child c = start(args, work / "study", "cases");
  ASSERT_TRUE(wait_until_stopped(c));
  const auto [r, seconds] = ended_by_sigterm(c, true);
  EXPECT_EQ(r.exit_code, 143) << r.out << r.err;
  EXPECT_LT(seconds, 20.0) << r.out;  // a case ends within a cycle of its signal
  EXPECT_NE(r.out.find("stopped  M = 100"), std::string::npos) << r.out;
  EXPECT_FALSE(fs::exists(study / "study.json"));
}

/// Whether `path` (a /proc entry) is gone within `limit`.
bool gone_within(const fs::path& path, std::chrono::seconds limit) {
  const auto deadline = std::chrono::steady_clock::now() + limit;
  while (fs::exists(path) && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  return !fs::exists(path);
}

TEST(Lifecycle, WhatTheFigureScriptStartedEndsWithTheStudy) {
  // The study signalled the script's process only: a `sleep` it had started
  // ran on after the study had ended.
  TempDir work;
  const fs::path study = work / "study";
  const fs::path script = work / "figures.sh";
  const fs::path started = work / "started";
  std::ofstream(script) << "sleep 60 & echo $! > " << quote(started.string()) << ".part\n"
                        << "mv " << quote(started.string()) << ".part " << quote(started.string())
                        << "\n"
                        << "wait\n";
  const Child c = start(tiny_study_with_script(study, script), work / "study");
  ASSERT_TRUE(wait_for_path(started));
  const std::string sleeper = "/proc/" + std::to_string(std::stoi(read_file(started)));
  ASSERT_TRUE(fs::exists(sleeper));
  kill(c.pid, SIGTERM);
  const Result r = result_of(c);
  EXPECT_EQ(r.exit_code, 143) << r.out << r.err;
  // Ended by the signal, and reaped by init: gone within moments.
  EXPECT_TRUE(gone_within(sleeper, std::chrono::seconds(10)))
      << "the figure script's sleep runs on";

  // Nor after a `kill -9` of the study alone, which can pass nothing on: the
  // script's guardian kills the group (a sleep of the script ran on).
  fs::remove(started);
  const Child killed = start(tiny_study_with_script(study, script), work / "killed");
  ASSERT_TRUE(wait_for_path(started));
  const std::string orphan = "/proc/" + std::to_string(std::stoi(read_file(started)));
  ASSERT_TRUE(fs::exists(orphan));
  kill(killed.pid, SIGKILL);
  EXPECT_EQ(result_of(killed).exit_code, 137);
  EXPECT_TRUE(gone_within(orphan, std::chrono::seconds(10))) << "the figure script's sleep runs on";

  // Nor does what a script that succeeded left running: it wrote into the
  // figures' staging directory after the study had ended.
  std::ofstream(script, std::ios::trunc) << "echo '{}' > \"$2/summary.json\"\n"
                                         << "(sleep 2; echo late > \"$1/late.txt\") &\n";
  const Child done = start(tiny_study_with_script(study, script), work / "done");
  EXPECT_EQ(exit_code_of(done), 0) << read_file(done.out) << read_file(done.err);
  std::this_thread::sleep_for(std::chrono::seconds(3));
  EXPECT_FALSE(fs::exists(study / "late.txt"));
}

TEST(Lifecycle, AFigureScriptsFailureIsReportedOnOneCleanLine) {
  TempDir work;
  const fs::path study = work / "study";
  const fs::path script = work / "figures.sh";
  const std::vector<std::string> args = tiny_study_with_script(study, script);
  // Escape sequences (clear the screen, red) are shown, not obeyed.
  std::ofstream(script) << "printf 'ok\\n\\033[2J\\033[31mbad\\n'; exit 3\n";
  const Result escaped = result_of(start(args, work / "escaped"));
  EXPECT_EQ(escaped.exit_code, 1);
  EXPECT_NE(escaped.out.find("  figure script failed (exit 3): ?[2J?[31mbad\n"), std::string::npos)
      << escaped.out;
  // A script killed by a signal, with nothing in its log, says how it ended.
  std::ofstream(script, std::ios::trunc) << "kill -SEGV $$\n";
  const Result killed = result_of(start(args, work / "killed"));
  EXPECT_EQ(killed.exit_code, 1);
  EXPECT_NE(killed.out.find("  figure script failed (exit 139): killed by SIGSEGV\n"),
            std::string::npos)
      << killed.out;
}

// ----------------------------------------------------------- ehlsim spike, publishing

const std::vector<std::string> kSpikeFiles = {"spike_snapshots.csv", "spike_profiles.csv",
                                              "axis_profiles.csv"};

/// The bytes of the named files of `dir`.
std::vector<std::string> contents_of(const fs::path& dir, const std::vector<std::string>& names) {
  std::vector<std::string> files;
  for (const std::string& name : names) files.push_back(read_file(dir / name));
  return files;
}

/// A finished 33^2 run in `work`/run with a snapshot per step, and three
/// earlier spike files told apart from any new ones by their content.
fs::path run_with_earlier_spike_files(const TempDir& work) {
  const fs::path run = work / "run";
  EXPECT_EQ(run_into(run, "--set time.T_end=0.3 --set output.snapshot_every=1").exit_code, 0);
  for (const std::string& name : kSpikeFiles) std::ofstream(run / name) << "earlier " << name;
  return run;
}

TEST(Lifecycle, SpikeReplacesItsThreeFilesInOneStep) {
  TempDir work;
  const fs::path run = run_with_earlier_spike_files(work);
  std::ofstream(run / "notes.txt") << "mine\n";  // the user's: stays
  const std::vector<std::string> before = contents(run);
  const TempDir elsewhere("expected");
  const fs::path expected = elsewhere / "spike";
  ASSERT_EQ(ehlsim("spike --quiet " + quote(run.string()) + " --out " + quote(expected.string()))
                .exit_code,
            0);
  EXPECT_EQ(names_in(expected), std::set<std::string>(kSpikeFiles.begin(), kSpikeFiles.end()));

  const Child c = start({"spike", "--quiet", run.string()}, work / "spike", "publish");
  ASSERT_TRUE(wait_until_stopped(c));
  // Just before the swap: DIR holds the earlier complete set, the staging
  // directory the new complete set beside links of everything else.
  EXPECT_EQ(contents(run), before);
  const fs::path staging = work / (".run.part-" + std::to_string(c.pid));
  EXPECT_EQ(names_in(staging), names_in(run));
  EXPECT_EQ(contents_of(staging, kSpikeFiles), contents_of(expected, kSpikeFiles));
  const Result r = resume(c, 0);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(contents_of(run, kSpikeFiles), contents_of(expected, kSpikeFiles));
  std::vector<std::string> rest = contents(run);
  std::vector<std::string> rest_before = before;
  const auto is_spike_file = [](const std::string& entry) {
    return std::any_of(kSpikeFiles.begin(), kSpikeFiles.end(),
                       [&](const std::string& name) { return entry.starts_with(name); });
  };
  std::erase_if(rest, is_spike_file);
  std::erase_if(rest_before, is_spike_file);
  EXPECT_EQ(rest, rest_before);  // every other file as it was
  EXPECT_EQ(names_in(work.path()), (std::set<std::string>{"run", "spike.err", "spike.out"}));
}

TEST(Lifecycle, ASignalEndsSpikeAndKeepsTheEarlierSpikeFiles) {
  // In the middle of the analysis (after its first snapshot) and just before the swap.
  for (const auto& [point, signal, code, name] : {std::tuple{"analysis", SIGTERM, 143, "SIGTERM"},
                                                  std::tuple{"publish", SIGINT, 130, "SIGINT"}}) {
    TempDir work(point);
    const fs::path run = run_with_earlier_spike_files(work);
    const std::vector<std::string> before = contents(run);
    const Child c = start({"spike", run.string()}, work / "spike", point);
    ASSERT_TRUE(wait_until_stopped(c)) << point;
    const Result r = resume(c, signal);
    EXPECT_EQ(r.exit_code, code) << point;
    EXPECT_EQ(r.err, std::string("ehlsim: interrupted by ") + name + ": the spike files in '" +
                         run.string() + "' were not changed\n");
    EXPECT_EQ(contents(run), before) << point;
    // No staging directory, no .part file, no lock.
    EXPECT_EQ(names_in(work.path()), (std::set<std::string>{"run", "spike.err", "spike.out"}));
  }
}

TEST(Lifecycle, SpikeRefusesTheStagingDirectoryOfARun) {
  // `ehlsim spike .run.part-PID` of a run paused before its swap was
  // accepted and swapped: the run then published spike files it never wrote.
  TempDir work;
  const fs::path run = work / "run";
  const Child c = start({"impact", "--quiet", "--set", "grid.points=33", "--set",
                         "body.elastic=false", "--set", "time.T_end=0.3", "--out", run.string()},
                        work / "impact", "publish");
  ASSERT_TRUE(wait_until_stopped(c));
  const fs::path staging = work / (".run.part-" + std::to_string(c.pid));
  const std::string refusal = "' is the staging directory of an ehlsim run into '" + run.string() +
                              "', one being written or left by a killed one: ehlsim spike reads "
                              "and amends finished runs only; use '" +
                              run.string() + "' once that run has ended\n";
  const std::set<std::string> staged = names_in(staging);
  Result r = ehlsim("spike --quiet " + quote(staging.string()));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.err, "ehlsim: error: run directory '" + staging.string() + refusal);
  const fs::path finished = work / "finished";
  ASSERT_EQ(run_into(finished, "--set time.T_end=0.3").exit_code, 0);
  r = ehlsim("spike --quiet " + quote(finished.string()) + " --out " + quote(staging.string()));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.err, "ehlsim: error: --out '" + staging.string() + refusal);
  EXPECT_EQ(names_in(staging), staged);
  r = resume(c, 0);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(names_in(run), staged);  // no spike files
  // What a killed run left (pid 999999 runs no more) is refused too.
  const fs::path left = work / ".gone.part-999999";
  fs::rename(finished, left);
  r = ehlsim("spike --quiet " + quote(left.string()));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.err, "ehlsim: error: run directory '" + left.string() +
                       "' is the staging directory of an ehlsim run into '" +
                       (work / "gone").string() +
                       "', one being written or left by a killed one: ehlsim spike reads and "
                       "amends finished runs only; use '" +
                       (work / "gone").string() + "' once that run has ended\n");
}

TEST(Lifecycle, SpikeFailsRatherThanDropAFileAddedMeanwhile) {
  TempDir work;
  const fs::path run = run_with_earlier_spike_files(work);
  const std::vector<std::string> before = contents(run);
  const Child c = start({"spike", "--quiet", run.string()}, work / "spike", "publish");
  ASSERT_TRUE(wait_until_stopped(c));
  // After the links were made, before the swap: another program writes into DIR.
  std::ofstream(run / "late.txt") << "written during the analysis\n";
  const Result r = resume(c, 0);
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(r.err, "ehlsim: error: '" + run.string() +
                       "' changed while its files were carried over (an entry added, removed or "
                       "replaced by another program): it was left as it was\n");
  std::vector<std::string> expected = before;
  expected.push_back("late.txtwritten during the analysis\n");
  std::sort(expected.begin(), expected.end());
  EXPECT_EQ(contents(run), expected);
  EXPECT_EQ(names_in(work.path()), (std::set<std::string>{"run", "spike.err", "spike.out"}));
}

/// A signal after the command has ended, in the moments before the process
/// exits, finds the spike files published: exit 0, as without it.  (The
/// handlers used to be restored there, and SIGTERM ended the process with 143
/// after the swap: SpikeSignalledAnyTimeLeavesOneCompleteSet caught it in CI.)
TEST(Lifecycle, ASignalAfterTheCommandEndedChangesNothing) {
  TempDir work;
  const fs::path run = run_with_earlier_spike_files(work);
  const TempDir elsewhere("expected");
  const fs::path expected = elsewhere / "spike";
  ASSERT_EQ(ehlsim("spike --quiet " + quote(run.string()) + " --out " + quote(expected.string()))
                .exit_code,
            0);
  for (const int signal : {SIGTERM, SIGINT, SIGHUP}) {
    const Child c = start({"spike", "--quiet", run.string()}, work / "spike", "exit");
    ASSERT_TRUE(wait_until_stopped(c)) << signal;
    const Result r = resume(c, signal);
    EXPECT_EQ(r.exit_code, 0) << signal;
    EXPECT_EQ(r.err, "") << signal;
    EXPECT_EQ(contents_of(run, kSpikeFiles), contents_of(expected, kSpikeFiles)) << signal;
  }
  EXPECT_EQ(names_in(work.path()), (std::set<std::string>{"run", "spike.err", "spike.out"}));

  // The same for a run of `ehlsim impact` (the guard is one for every command).
  const fs::path reference = elsewhere / "impact";
  ASSERT_EQ(run_into(reference, "--set time.T_end=0.3").exit_code, 0);
  const fs::path published = work / "impact-run";
  const Child c =
      start({"impact", "--quiet", "--set", "grid.points=33", "--set", "body.elastic=false", "--set",
             "time.T_end=0.3", "--out", published.string()},
            work / "impact", "exit");
  ASSERT_TRUE(wait_until_stopped(c));
  const Result r = resume(c, SIGTERM);
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_EQ(r.err, "");
  EXPECT_EQ(names_in(published), names_in(reference));
  EXPECT_EQ(read_file(published / "timeseries.csv"), read_file(reference / "timeseries.csv"));
}

/// Whether `c` has ended (it stays waitable).
bool has_ended(const Child& c) {
  siginfo_t info{};
  return waitid(P_PID, static_cast<id_t>(c.pid), &info, WEXITED | WNOHANG | WNOWAIT) == 0 &&
         info.si_pid == c.pid;
}

/// With a real signal at a moment the test does not choose (no hook): `ehlsim
/// spike` ends either published (exit 0, the new set) or interrupted (exit
/// 143, the earlier set), never with a mix or debris.
TEST(Lifecycle, SpikeSignalledAnyTimeLeavesOneCompleteSet) {
  TempDir work;
  const fs::path run = work / "run";
  // 417 snapshots of 33^2 (1 s; 10 s under the sanitizers).
  const Child impact = start({"impact", "--quiet", "--out", run.string(), "--set", "grid.points=33",
                              "--set", "time.dT=0.01", "--set", "output.snapshot_every=1"},
                             work / "impact");
  ASSERT_EQ(exit_code_of(impact), 0) << read_file(impact.err);
  const TempDir elsewhere("expected");
  ASSERT_EQ(ehlsim("spike --quiet " + quote(run.string()) + " --out " +
                   quote((elsewhere / "spike").string()))
                .exit_code,
            0);
  const std::vector<std::string> fresh = contents_of(elsewhere / "spike", kSpikeFiles);
  int interrupted = 0;
  // The analysis takes 0.1 to 0.3 s: the later signals may come after the swap.
  for (const int delay_ms : {0, 20, 100, 400}) {
    for (const std::string& name : kSpikeFiles) std::ofstream(run / name) << "earlier " << name;
    const std::vector<std::string> earlier = contents_of(run, kSpikeFiles);
    const Child c = start({"spike", "--quiet", run.string()}, work / "spike");
    // Once it holds the lock (or has ended already).
    const fs::path staging = work / (".run.part-" + std::to_string(c.pid));
    const auto until = std::chrono::steady_clock::now() + kPatience;
    while (!fs::exists(staging) && !has_ended(c) && std::chrono::steady_clock::now() < until)
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    std::this_thread::sleep_for(std::chrono::milliseconds(delay_ms));
    kill(c.pid, SIGTERM);
    const int code = exit_code_of(c);
    if (code == 0) {
      EXPECT_EQ(contents_of(run, kSpikeFiles), fresh) << delay_ms;
    } else {
      ++interrupted;
      EXPECT_EQ(code, 143) << delay_ms;
      EXPECT_EQ(read_file(c.err), "ehlsim: interrupted by SIGTERM: the spike files in '" +
                                      run.string() + "' were not changed\n");
      EXPECT_EQ(contents_of(run, kSpikeFiles), earlier) << delay_ms;
    }
    EXPECT_EQ(names_in(work.path()),
              (std::set<std::string>{"impact.err", "impact.out", "run", "spike.err", "spike.out"}))
        << delay_ms;
  }
  EXPECT_GT(interrupted, 0);  // the signal right after the lock comes before the swap
}

/// The child processes of `pid` (none once it has ended).
std::vector<pid_t> children_of(pid_t pid) {
  const std::string task = std::to_string(pid);
  std::ifstream in("/proc/" + task + "/task/" + task + "/children");
  std::vector<pid_t> children;
  for (pid_t child = 0; in >> child;) children.push_back(child);
  return children;
}

/// Waits until `c` has a child process (its read of an untrusted file, done in
/// a child first: io/IsolatedIo.hpp) and returns its pid; -1 after kPatience.
pid_t wait_for_reader(const Child& c) {
  const auto until = std::chrono::steady_clock::now() + kPatience;
  while (std::chrono::steady_clock::now() < until && !has_ended(c)) {
    if (const std::vector<pid_t> children = children_of(c.pid); !children.empty())
      return children.front();
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  return -1;
}

/// HDF5 loops for ever on these files, and before, SIGTERM and SIGINT only set
/// the flag a time step looks at: kill -9 alone ended the command.
TEST(Lifecycle, ASignalWhileHdf5HangsOnAFileEndsTheCommandAndItsReader) {
  TempDir work;
  const fs::path checkpoint = library_crash("checkpoint-hdf5-H5HG-heap-loop.nc");
  const fs::path out = work / "out";
  const fs::path run = work / "run";
  fs::create_directories(run);
  std::ofstream(run / "run.json") << ehlsim::testing::minimal_run_json();
  fs::copy_file(library_crash("fields-hdf5-H5HG-heap-loop.nc"), run / "fields.nc");
  const std::vector<std::tuple<std::vector<std::string>, int, std::string>> cases = {
      {{"impact", "--quiet", "--set", "grid.points=9", "--set", "solver.coarsest_points=5",
        "--restart", checkpoint.string(), "--out", out.string()},
       SIGTERM,
       "ehlsim: interrupted by SIGTERM while checkpoint '" + checkpoint.string() +
           "' was read, before the run started: '" + out.string() +
           "' was not changed; run the command again\n"},
      {{"spike", run.string()},
       SIGINT,
       "ehlsim: interrupted by SIGINT: the spike files in '" + run.string() +
           "' were not changed\n"}};
  for (const auto& [args, signal, message] : cases) {
    const Child c = start(args, work / "command");
    const pid_t reader = wait_for_reader(c);
    ASSERT_GT(reader, 0) << args.front();
    kill(c.pid, signal);
    const Result r = result_of(c);
    EXPECT_EQ(r.exit_code, 128 + signal) << args.front();
    EXPECT_EQ(r.err, message);
    EXPECT_TRUE(kill(reader, 0) != 0 && errno == ESRCH) << "the reader lives on";
  }
  EXPECT_EQ(names_in(work.path()), (std::set<std::string>{"command.err", "command.out", "run"}));
  EXPECT_EQ(names_in(run), (std::set<std::string>{"fields.nc", "run.json"}));
}

TEST(Lifecycle, ASignalWhileTheRunIsPublishedLeavesTheEarlierRun) {
  TempDir work;
  const fs::path run = work / "run";
  ASSERT_EQ(run_into(run, "--set time.T_end=0.2").exit_code, 0);
  const std::vector<std::string> before = contents(run);
  const std::vector<std::string> args = {"impact", "--quiet",
                                         "--set",  "grid.points=33",
                                         "--set",  "body.elastic=false",
                                         "--set",  "time.T_end=0.3",
                                         "--set",  "output.checkpoint_every=2",
                                         "--out",  run.string()};
  // After the last step, its files written into the staging directory.
  const Child c = start(args, work / "impact", "publish");
  ASSERT_TRUE(wait_until_stopped(c));
  const Result r = resume(c, SIGTERM);
  EXPECT_EQ(r.exit_code, 143);
  // The checkpoint is of the run's last step (it reached time.T_end): the
  // resume command it was given was refused ("time.T_end = 0.3: must be
  // later than the time of checkpoint"), so none is offered.
  const std::regex message(
      "ehlsim: interrupted by SIGTERM after the last step, before the run was published: '" +
      run.string() +
      "' was not changed; its checkpoint is of its last step \\([0-9]+\\), which leaves nothing "
      "to resume: run the command again\n");
  EXPECT_TRUE(std::regex_match(r.err, message)) << r.err;
  EXPECT_EQ(contents(run), before);
  EXPECT_EQ(names_in(work.path()),
            (std::set<std::string>{"impact.err", "impact.out", "run", "run.checkpoint.nc"}));

  // Without checkpoints (output.checkpoint_every = 0) there is nothing to resume from.
  std::vector<std::string> without = args;
  without.at(9) = "output.checkpoint_every=0";
  const Child bare = start(without, work / "bare", "publish");
  ASSERT_TRUE(wait_until_stopped(bare));
  const Result unkept = resume(bare, SIGINT);
  EXPECT_EQ(unkept.exit_code, 130);
  EXPECT_EQ(unkept.err,
            "ehlsim: interrupted by SIGINT after the last step, before the run was published: '" +
                run.string() +
                "' was not changed; no checkpoint was written: run the command again\n");
  EXPECT_EQ(contents(run), before);

  // The hook only delays: let go without a signal, the run publishes what it
  // publishes without the hook.
  const Child again = start(args, work / "again", "publish");
  ASSERT_TRUE(wait_until_stopped(again));
  ASSERT_EQ(resume(again, 0).exit_code, 0);
  const fs::path plain = work / "plain";
  ASSERT_EQ(run_into(plain, "--set time.T_end=0.3 --set output.checkpoint_every=2").exit_code, 0);
  EXPECT_EQ(read_file(run / "timeseries.csv"), read_file(plain / "timeseries.csv"));
  EXPECT_EQ(nlohmann::json::parse(read_file(run / "run.json"))["results"],
            nlohmann::json::parse(read_file(plain / "run.json"))["results"]);
}

TEST(Lifecycle, ARunPublishesTheCheckpointItReadOrWroteNotWhatItsFileBecame) {
  // A restart that ends before its next checkpoint publishes the one it
  // resumed from.  Taken from the file at the end, that was whatever the
  // file had become: another case's checkpoint (exit 0), a FIFO, or nothing,
  // and the finished run failed (exit 1).
  TempDir work;
  const std::vector<std::string> args = {"impact",         "--quiet", "--set",
                                         "grid.points=33", "--set",   "output.checkpoint_every=4"};
  std::vector<std::string> full = args;
  full.insert(full.end(), {"--out", (work / "full").string()});
  ASSERT_EQ(result_of(start(full, work / "full")).exit_code, 0);  // lift-off 2 steps after one
  const std::string read = read_file(work / "full" / "checkpoint.nc");
  for (const bool remove : {false, true}) {
    const fs::path source = work / "resume.nc";
    write_file(source, read);
    const fs::path dir = work / (remove ? "removed" : "replaced");
    std::vector<std::string> again = args;
    again.insert(again.end(), {"--restart", source.string(), "--out", dir.string()});
    const Child c = start(again, dir.string() + "-capture", "publish");
    ASSERT_TRUE(wait_until_stopped(c));
    fs::remove(source);
    if (!remove) {
      ASSERT_EQ(::mkfifo(source.c_str(), 0644), 0);
    }
    const Result r = resume(c, 0);
    EXPECT_EQ(r.exit_code, 0) << r.err;
    EXPECT_TRUE(fs::is_regular_file(fs::symlink_status(dir / "checkpoint.nc")));
    EXPECT_EQ(read_file(dir / "checkpoint.nc"), read);
    fs::remove(source);
  }
  // So does a run whose own DIR.checkpoint.nc was replaced, written over or
  // removed: the other file was published as its checkpoint (exit 0), and
  // deleted; or the finished run failed (exit 1).
  for (const std::string how : {"replaced", "written_over", "removed"}) {
    const fs::path dir = work / ("own_" + how);
    const fs::path beside = dir.string() + ".checkpoint.nc";
    std::vector<std::string> own = args;
    own.insert(own.end(), {"--out", dir.string()});
    const Child c = start(own, dir.string() + "-capture", "publish");
    ASSERT_TRUE(wait_until_stopped(c));
    if (how != "written_over") fs::remove(beside);
    if (how != "removed") write_file(beside, "not the run's\n");
    const Result r = resume(c, 0);
    EXPECT_EQ(r.exit_code, 0) << r.err;
    EXPECT_EQ(read_file(dir / "checkpoint.nc"), read) << how;
    if (how != "removed") {
      EXPECT_EQ(read_file(beside), "not the run's\n") << how;  // it stays
    }
  }
}

TEST(Lifecycle, ARunThatEndedInASubdirectoryMeanwhileIsNotDeleted) {
  // A run into run/inner, or `ehlsim spike run --out run/gauss`, that ended
  // while a run into run was going: its files have ehlsim's names and its
  // lock is gone, and the outer run's swap deleted them with exit 0.
  TempDir work;
  const fs::path run = work / "run";
  ASSERT_EQ(run_into(run, "--set time.T_end=0.2").exit_code, 0);
  const std::vector<std::string> before = contents(run);
  const std::vector<std::string> args = {
      "impact", "--quiet",        "--set", "grid.points=33", "--set", "body.elastic=false",
      "--set",  "time.T_end=0.3", "--out", run.string()};
  const Child outer = start(args, work / "outer", "publish");
  ASSERT_TRUE(wait_until_stopped(outer));
  ASSERT_EQ(run_into(run / "inner", "--set time.T_end=0.1").exit_code, 0);
  const Result r = resume(outer, 0);
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("'" + run.string() + "' gained '" + (run / "inner").string() +
                       "' during the run (another program or ehlsim run wrote it): it was left "
                       "as it was"),
            std::string::npos)
      << r.err;
  EXPECT_TRUE(fs::exists(run / "inner" / "run.json"));
  fs::remove_all(run / "inner");
  EXPECT_EQ(contents(run), before);  // the earlier run, as it was
}

TEST(Lifecycle, ASignalWhileTheConfigIsReadEndsAsASignal) {
  // A config file that is a FIFO no one writes to blocks its reader; a
  // SIGTERM there ended as bad input ("Interrupted system call", exit 2).
  TempDir work;
  const fs::path fifo = work / "config.toml";
  ASSERT_EQ(mkfifo(fifo.c_str(), 0600), 0);
  const Child c =
      start({"impact", fifo.string(), "--out", (work / "run").string()}, work / "impact");
  // Blocked in the open of the FIFO (the kernel waits for a writer).
  const fs::path wchan = fs::path("/proc") / std::to_string(c.pid) / "wchan";
  ASSERT_TRUE(wait_for_text(wchan, "wait_for_partner"));
  kill(c.pid, SIGTERM);
  const Result r = result_of(c);
  EXPECT_EQ(r.exit_code, 143);
  EXPECT_EQ(r.err,
            "ehlsim: interrupted by SIGTERM while the input was read (cannot read config "
            "file '" +
                fifo.string() + "': Interrupted system call): nothing was written\n");
  EXPECT_FALSE(fs::exists(work / "run"));
}

TEST(Lifecycle, AStudyKeepsAFileOfTheUsersInItsFigures) {
  // figures/ is replaced as a whole: a file of the user's there was deleted
  // with the earlier set (exit 0).  It is carried over; a figure of the new
  // set replaces the earlier one.
  TempDir work;
  const fs::path study = work / "study";
  const fs::path script = work / "figures.sh";
  std::ofstream(script) << "echo new > \"$2/fig1.png\"; echo '{}' > \"$2/summary.json\"\n";
  fs::create_directories(study / "figures");
  std::ofstream(study / "figures" / "mine.txt") << "mine\n";
  std::ofstream(study / "figures" / "fig1.png") << "earlier\n";
  const Child c = start(tiny_study_with_script(study, script), work / "study");
  ASSERT_EQ(exit_code_of(c), 0) << read_file(c.out) << read_file(c.err);
  EXPECT_EQ(read_file(study / "figures" / "mine.txt"), "mine\n");
  EXPECT_EQ(read_file(study / "figures" / "fig1.png"), "new\n");
}

}  // namespace
