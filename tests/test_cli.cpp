// The ehlsim command: exit codes and one-line error messages for bad input,
// --help / --version, and one tiny real run.
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <netcdf.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "io/Checkpoint.hpp"
#include "io/FieldWriter.hpp"
#include "io/ThreadBudget.hpp"
#include "support/CheckpointDamage.hpp"
#include "support/MemoryGuardCheck.hpp"
#include "support/MinimalRun.hpp"
#include "support/RunEhlsim.hpp"
#include "support/TempDir.hpp"
#include "support/TestPaths.hpp"

namespace {

namespace fs = std::filesystem;

using ehlsim::available_cores;
using ehlsim::testing::ehlsim;
using ehlsim::testing::library_crash;
using ehlsim::testing::quote;
using ehlsim::testing::read_file;
using ehlsim::testing::Result;
using ehlsim::testing::source_dir;
using ehlsim::testing::TempDir;
using ehlsim::testing::write_file;

/// Bad input: exit code 2 and exactly `message` on one line of stderr.
void expect_bad_input(const Result& r, const std::string& message) {
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.err, "ehlsim: error: " + message + "\n");
  EXPECT_EQ(r.out, "");
}

/// A failed command: exit code 1 and exactly `message` on one line of stderr.
void expect_failure(const Result& r, const std::string& message) {
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(r.err, "ehlsim: error: " + message + "\n");
  EXPECT_EQ(r.out, "");
}

TEST(Cli, UnknownKeyInFile) {
  TempDir dir;
  const std::string f = write_file(dir / "case.toml", "[case]\nMx = 20\n").string();
  expect_bad_input(
      ehlsim("impact " + quote(f)),
      "unknown key 'case.Mx' (known keys in [case]: M, L, lambda_bar, alpha_bar) (" + f + ":2:6)");
}

TEST(Cli, UnknownKeyInSet) {
  expect_bad_input(ehlsim("impact --set grid.point=33"),
                   "unknown key 'grid.point' (known keys in [grid]: points, half_width) (--set)");
}

TEST(Cli, WrongType) {
  expect_bad_input(ehlsim("impact --set case.M=abc"),
                   "case.M = \"abc\": must be a number > 0 (--set)");
  expect_bad_input(ehlsim("impact --set body.elastic=1"),
                   "body.elastic = 1: must be true or false (--set)");
}

// A NUL in a TOML string or key ("\u0000") ended the line there: the
// exception's what() is a C string.  Shown as the escape cli::printable uses.
TEST(Cli, ANulInAValueOrKeyIsShownAndTheLineGoesOn) {
  expect_bad_input(ehlsim("impact --set " + quote("case.M=\"x\\u0000y\"")),
                   "case.M = \"x\\x00y\": must be a number > 0 (--set)");
  expect_bad_input(ehlsim("rolling --set " + quote("case.M=\"x\\u0000y\"")),
                   "case.M = \"x\\x00y\": must be a number > 0 (--set)");
  TempDir dir;
  const std::string f = write_file(dir / "case.toml", "[case]\n\"M\\u0000x\" = 3\n").string();
  expect_bad_input(ehlsim("impact " + quote(f)),
                   "unknown key 'case.M\\x00x' (known keys in [case]: M, L, lambda_bar, "
                   "alpha_bar) (" +
                       f + ":2:14)");
}

TEST(Cli, OutOfRange) {
  expect_bad_input(ehlsim("impact --set case.M=-3"), "case.M = -3: must be > 0 (--set)");
  TempDir dir;
  const std::string f = write_file(dir / "case.toml", "[time]\nV0 = 0\n").string();
  expect_bad_input(ehlsim("impact " + quote(f)),
                   "time.V0 = 0: must be in [1e-06, 1e+06] (" + f + ":2:6)");
}

TEST(Cli, GridNotTwoToTheKPlusOne) {
  expect_bad_input(ehlsim("impact --set grid.points=100"),
                   "grid.points = 100: must be 2^k + 1 between 9 and 4097 (--set)");
}

TEST(Cli, UnreadableFile) {
  TempDir dir;
  const std::string f = (dir / "missing.toml").string();
  expect_bad_input(ehlsim("impact " + quote(f)),
                   "cannot read config file '" + f + "': No such file or directory");
}

TEST(Cli, MalformedToml) {
  TempDir dir;
  const std::string f = write_file(dir / "bad.toml", "[case]\nM = = 3\n").string();
  const Result r = ehlsim("impact " + quote(f));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.err.rfind("ehlsim: error: " + f + ":2:", 0), 0u) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
}

TEST(Cli, BadCommandLine) {
  for (const char* args :
       {"", "impact --bogus", "impact a.toml b.toml", "impact --set", "frobnicate"}) {
    SCOPED_TRACE(args);
    const Result r = ehlsim(args);
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_EQ(r.err.rfind("ehlsim: error: ", 0), 0u) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  }
}

TEST(Cli, EmptyPathsAreBadInput) {
  expect_bad_input(ehlsim("impact --restart ''"),
                   "--restart: must name a checkpoint file, not be empty");
  expect_bad_input(ehlsim("impact --out ''"), "--out: must name a directory, not be empty");
  expect_bad_input(ehlsim("study --out ''"), "--out: must name a directory, not be empty");
  // ehlsim spike took it for its default, the run directory.
  expect_bad_input(ehlsim("spike some-run --out ''"), "--out: must name a directory, not be empty");
}

TEST(Cli, AnOutThatIsOrLiesInAFileIsBadInput) {
  TempDir dir;
  const fs::path file = write_file(dir / "afile", "x");
  const std::string in_file = (file / "sub").string();
  const std::string is_file = "--out '" + file.string() + "' exists and is not a directory";
  const std::string below = "--out '" + in_file + "': '" + file.string() + "' is not a directory";
  expect_bad_input(ehlsim("impact --set grid.points=33 --out " + quote(in_file)), below);
  expect_bad_input(ehlsim("rolling --set grid.points=33 --out " + quote(in_file)), below);
  expect_bad_input(ehlsim("study --grid 33 --no-plots --out " + quote(in_file)), below);
  expect_bad_input(ehlsim("study --grid 33 --no-plots --out " + quote(file.string())), is_file);
  expect_bad_input(ehlsim("rolling --set grid.points=33 --out " + quote(file.string())), is_file);
  // ... also where the lock file beside it cannot be made (as beside a file in
  // an unwritable directory): the file is named before the lock is tried.
  fs::create_directory(dir / ".afile.lock");
  for (const std::string command : {"impact --set grid.points=33", "rolling --set grid.points=33",
                                    "study --grid 33 --no-plots"})
    expect_bad_input(ehlsim(command + " --out " + quote(file.string())), is_file);
  EXPECT_EQ(read_file(file), "x");
  EXPECT_EQ(std::distance(fs::directory_iterator(dir.path()), fs::directory_iterator()), 2);
}

TEST(Cli, UnknownCommandIsNamed) {
  expect_bad_input(ehlsim("frobnicate --out x"),
                   "unknown command 'frobnicate' (commands: impact, spike, study, rolling; try "
                   "ehlsim --help)");
}

TEST(Cli, AnOptionInPlaceOfAValueIsRefused) {
  // `--out --set case.M=5` took "--set" as the directory and then read
  // "case.M=5" as the config file.
  expect_bad_input(ehlsim("impact --out --set case.M=5"),
                   "--out = --set: looks like an option, not a directory: write ./--set for a "
                   "name that starts with '-'");
  expect_bad_input(ehlsim("impact --restart -x"),
                   "--restart = -x: looks like an option, not a checkpoint file: write ./-x for a "
                   "name that starts with '-'");
  expect_bad_input(ehlsim("study --python -q --no-plots"),
                   "--python = -q: looks like an option, not a program: write ./-q for a name "
                   "that starts with '-'");
  expect_bad_input(ehlsim("rolling --out -"),
                   "--out = -: looks like an option, not a directory: write ./- for a name that "
                   "starts with '-'");
  expect_bad_input(ehlsim("impact --out==x"),
                   "--out = =x: starts with '=' (one '=' too many?): write ./=x for a name that "
                   "starts with '='");
  // Flags take no value: --quiet=5 ran as --quiet.
  expect_bad_input(ehlsim("impact --quiet=5 --out x"),
                   "--quiet=5: --quiet takes no value (see --help)");
  expect_bad_input(ehlsim("rolling --quiet=no --out x"),
                   "--quiet=no: --quiet takes no value (see --help)");
  expect_bad_input(ehlsim("study --no-plots=1 --out x"),
                   "--no-plots=1: --no-plots takes no value (see --help)");
  // ... and --quiet=true, which CLI11's flag override check let through.
  expect_bad_input(ehlsim("impact --quiet=true --out x"),
                   "--quiet=true: --quiet takes no value (see --help)");
  expect_bad_input(ehlsim("spike -q=1 x"), "-q=1: -q takes no value (see --help)");
  expect_bad_input(ehlsim("impact -qq=1 --out x"), "-qq=1: -q takes no value (see --help)");
  // CLI11 read -q-out=x as -q --out=x, -q- as -q, and '-q ' as -q with the
  // config file '- '.
  const std::string kStray =
      ": a group of short options holds a character that names none: give each option on its "
      "own (see --help)";
  expect_bad_input(ehlsim("impact -q-out=x"), "-q-out=x" + kStray);
  expect_bad_input(ehlsim("impact -q- --out x"), "-q-" + kStray);
  expect_bad_input(ehlsim("impact '-q ' --out x"), "-q " + kStray);
  expect_bad_input(ehlsim("impact -q@x --out x"), "-q@x" + kStray);
  // A short option's '=' is part of its value for CLI11: -o=x made "=x".
  expect_bad_input(ehlsim("impact -o=x"),
                   "-o=x: a short option takes its value after a space: -o VALUE or --out=VALUE");
  expect_bad_input(ehlsim("impact -qo=x"),
                   "-qo=x: a short option takes its value after a space: -o VALUE or --out=VALUE");
  // An option of the command before it was told only "not expected".
  expect_bad_input(ehlsim("--quiet=1 impact --out x"),
                   "--quiet=1: options follow the command: ehlsim impact --quiet=1 ...");
  expect_bad_input(ehlsim("-o x rolling"), "-o: options follow the command: ehlsim rolling -o ...");
  // ... also where the option's value is a command's name.
  expect_bad_input(ehlsim("-o impact rolling"),
                   "-o: options follow the command: ehlsim rolling -o ...");
  // An option of ehlsim itself, not of the command (CLI11: "not expected").
  expect_bad_input(ehlsim("impact --version=1"),
                   "--version=1: an option of ehlsim itself, not of impact: ehlsim --version");
  expect_bad_input(ehlsim("rolling --version"),
                   "--version: an option of ehlsim itself, not of rolling: ehlsim --version");
  // After "--" everything is positional: a config file named so.
  expect_bad_input(ehlsim("impact --out x -- --quiet=1"),
                   "cannot read config file '--quiet=1': No such file or directory");
  // Empty values: the positional config ran the built-in case.
  expect_bad_input(ehlsim("impact --out x -- ''"), "config: must name a config file, not be empty");
  expect_bad_input(ehlsim("impact --out="), "--out is given no value (see --help)");
  // CLI11 read 0x21 as 33 and 0b1 as 1.
  const std::string kWholeNumber =
      "must be a whole number of at most 2147483647 in decimal digits (see --help)";
  expect_bad_input(ehlsim("study --grid 0x21 --out x"), "--grid = 0x21: " + kWholeNumber);
  expect_bad_input(ehlsim("study --jobs 0b1 --out x"), "--jobs = 0b1: " + kWholeNumber);
  expect_bad_input(ehlsim("study --rolling-grid=-5 --out x"),
                   "--rolling-grid = -5: " + kWholeNumber);
  // ... and 011 as octal 9: leading zeros are dropped.
  expect_bad_input(ehlsim("study --grid 011 --out x"),
                   "--grid = 11: must be 2^k + 1 between 9 and 4097 (the points per side of every "
                   "impact case)");
}

TEST(Cli, CommandLineErrorsSayWhatIsAllowed) {
  // CLI11's own texts: "Could not convert: --grid = abc", "--out: At Most 1
  // required but received 2", "A subcommand is required".
  expect_bad_input(
      ehlsim("study --grid abc --out x"),
      "--grid = abc: must be a whole number of at most 2147483647 in decimal digits (see "
      "--help)");
  expect_bad_input(
      ehlsim("study --jobs 2.5 --out x"),
      "--jobs = 2.5: must be a whole number of at most 2147483647 in decimal digits (see "
      "--help)");
  expect_bad_input(ehlsim("rolling --out a --out b"), "--out is given 2 times: give it once");
  expect_bad_input(ehlsim("--bogus"),
                   "'--bogus' is neither a command nor an option of ehlsim (commands: impact, "
                   "spike, study, rolling; try ehlsim --help)");
  // ... also before another option (--version printed the version, exit 0).
  expect_bad_input(ehlsim("--bogus --version"),
                   "'--bogus' is neither a command nor an option of ehlsim (commands: impact, "
                   "spike, study, rolling; try ehlsim --help)");
  // An escape character of an argument reached the terminal raw.
  expect_bad_input(ehlsim("impact " + quote("--bo\x1bgus")),
                   "'--bo\\x1bgus': not expected by ehlsim impact: an option it does not have, or "
                   "one argument too many (see ehlsim impact --help)");
  // CLI11 listed the arguments backwards, with the "--" before them, and said
  // nothing of what is allowed.
  expect_bad_input(ehlsim("impact -- a.toml b.toml c.toml"),
                   "'b.toml', 'c.toml': not expected by ehlsim impact: an option it does not "
                   "have, or one argument too many (see ehlsim impact --help)");
  // A newline read as a space named another file ('cfg .toml').
  expect_bad_input(ehlsim("impact " + quote("cfg\n.toml")),
                   "cannot read config file 'cfg\\x0a.toml': No such file or directory");
  expect_bad_input(ehlsim(""),
                   "no command given (commands: impact, spike, study, rolling; try ehlsim --help)");
  // A terminal acts on UTF-8's C1 controls (U+009B is a CSI) and the
  // bidirectional overrides (U+202E reverses what follows), shows zero-width
  // characters (U+200B) as nothing and, in an 8-bit charset, takes bytes that
  // form no UTF-8 character (an overlong U+07FF here) for C1: all escaped.
  // Other UTF-8 text stays as it is.
  expect_bad_input(
      ehlsim("impact " + quote("cfg\xc2\x9b"
                               "31m\xe2\x80\xae\x9b-\xc3\xa9\xe0\x9f\xbf\xe2\x80\x8b.toml")),
      "cannot read config file "
      "'cfg\\xc2\\x9b31m\\xe2\\x80\\xae\\x9b-\xc3\xa9\\xe0\\x9f\\xbf\\xe2\\x80\\x8b.toml': "
      "No such file or directory");
}

TEST(Cli, RunawayValuesAreShortenedInErrors) {
  TempDir dir;
  constexpr std::size_t kBytes = 10'000'000;
  const std::string f =
      write_file(dir / "big.toml", "[case]\nM = \"" + std::string(kBytes, 'a') + "\"\n").string();
  // 80 characters of the value as written (quote included), then its size.
  expect_bad_input(ehlsim("impact " + quote(f)),
                   "case.M = \"" + std::string(79, 'a') +
                       "... (10000002 bytes): must be a number > 0 (" + f + ":2:5)");
  // Through CLI11 too: a word longer than any path is shortened.
  const Result r = ehlsim("study --jobs " + std::string(100'000, '7'));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_LT(r.err.size(), 300u) << r.err.substr(0, 300);
  EXPECT_NE(r.err.find("... (100000 bytes)"), std::string::npos) << r.err.substr(0, 300);
  // A path longer than any file name keeps its quotes and the punctuation
  // after it, and its size is the path's.
  fs::path deep = dir.path();
  for (int i = 0; i < 22; ++i) deep /= std::string(200, 'b');
  const std::string out = (deep / "run").string();
  const Result long_path = ehlsim("impact --quiet --out " + quote(out));
  EXPECT_EQ(long_path.exit_code, 1);
  EXPECT_NE(long_path.err.find(fmt::format("... ({} bytes)', the parent directory of --out '",
                                           deep.string().size())),
            std::string::npos)
      << long_path.err;
  EXPECT_NE(long_path.err.find(fmt::format("... ({} bytes)': File name too long\n", out.size())),
            std::string::npos)
      << long_path.err;
}

TEST(Cli, ADirectoryNamedWithBytesThatAreNoTextIsWrittenAndShownSafely) {
  // --out $'o\xc2\x9b\x80': the report printed U+009B (a CSI) raw, and
  // run.json could not be written after the last step (a byte that is no
  // UTF-8): the run was lost with exit 1.
  TempDir dir;
  const auto run_into = [](const fs::path& out) {
    return ehlsim("impact --set grid.points=33 --set body.elastic=false --set time.T_end=0.1 " +
                  std::string("--out ") + quote(out.string()));
  };
  const std::string name =
      "o\xc2\x9b"
      "\x80";
  const Result r = run_into(dir / name);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.out.find("\xc2\x9b"), std::string::npos);
  EXPECT_NE(r.out.find("o\\xc2\\x9b\\x80"), std::string::npos) << r.out;
  const auto json = nlohmann::json::parse(read_file(dir / name / "run.json"));
  EXPECT_EQ(json["invocation"]["out"], (dir / "o\xc2\x9b\xef\xbf\xbd").string());  // U+FFFD
  // A newline of the name broke the report's lines.
  const Result nl = run_into(dir / "n\nl");
  ASSERT_EQ(nl.exit_code, 0) << nl.err;
  EXPECT_NE(nl.out.find("n\\x0al\n"), std::string::npos) << nl.out;
  EXPECT_EQ(nl.out.find("n\nl"), std::string::npos) << nl.out;
}

TEST(Cli, ARunDirectoryNamedWithALeadingBlankOrLikeAUrlIsReadAndContinued) {
  // libnetcdf drops the leading blanks and control characters of a file
  // name: `spike ' r'` could not read the fields.nc that `impact --out ' r'`
  // had written, and the checkpoint went to ./r.checkpoint.nc.part, after
  // which the run failed ("cannot sync ' r.checkpoint.nc.part'").
  TempDir dir;
  const std::string in_dir = "cd " + quote(dir.path().string()) + " && ";
  const std::string tiny = "--quiet --set grid.points=33 --set time.T_end=1 ";
  const Result run =
      ehlsim("impact " + tiny + "--set output.checkpoint_every=5 --out ' r'", in_dir);
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_TRUE(fs::exists(dir / " r" / "checkpoint.nc"));
  EXPECT_FALSE(fs::exists(dir / "r.checkpoint.nc.part"));
  const Result spike = ehlsim("spike ' r'", in_dir);
  EXPECT_EQ(spike.exit_code, 0) << spike.err;
  EXPECT_TRUE(fs::exists(dir / " r" / "spike_snapshots.csv"));
  // A tab leads the name of the checkpoint to continue from.
  fs::copy(dir / " r", dir / "\t r", fs::copy_options::recursive);
  const Result resumed = ehlsim("impact " + tiny + "--set time.T_end=1.2 --restart " +
                                    quote("\t r/checkpoint.nc") + " --out r2",
                                in_dir);
  EXPECT_EQ(resumed.exit_code, 0) << resumed.err;
  // And it took a name with "://" for a URL: the checkpoint of a run into
  // q://r failed ("nc_create: NetCDF: Invalid argument"), and spike could not read it.
  const Result url =
      ehlsim("impact " + tiny + "--set output.checkpoint_every=5 --out q://r", in_dir);
  ASSERT_EQ(url.exit_code, 0) << url.err;
  EXPECT_TRUE(fs::exists(dir / "q:" / "r" / "checkpoint.nc"));
  const Result url_spike = ehlsim("spike q://r", in_dir);
  EXPECT_EQ(url_spike.exit_code, 0) << url_spike.err;
}

TEST(Cli, RuntimeFailureIsExitOneWithOneLine) {
  // (An --out below a file, once the example here, is bad input:
  // AnOutThatIsOrLiesInAFileIsBadInput.)
  TempDir dir;
  const Result r = ehlsim("impact --quiet --set grid.points=33 --set time.max_steps=2 --out " +
                          quote((dir / "run").string()));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(r.err.rfind("ehlsim: error: time step 2 ", 0), 0u) << r.err;
  EXPECT_NE(r.err.find("no lift-off after 2 steps (time.max_steps"), std::string::npos) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_FALSE(fs::exists(dir / "run"));
  // A time too short for five decimals is shown with its digits ("T = 0.00000").
  const Result short_steps = ehlsim(
      "impact --quiet --set grid.points=33 --set time.dT=1e-6 --set time.max_steps=5 --out " +
      quote((dir / "run").string()));
  EXPECT_EQ(short_steps.err.rfind("ehlsim: error: time step 5 (T = 5e-06): no lift-off", 0), 0u)
      << short_steps.err;
}

// OMP_NUM_THREADS=100000 crashed in libgomp's first parallel region (SIGSEGV,
// a staging directory left); 1000 ran for minutes instead of seconds.  The
// team is at most the cores.  A value libgomp ignores is bad input.
TEST(Cli, OmpNumThreadsIsAtMostTheCoresAndAWholeNumber) {
  TempDir dir;
  const std::string out = quote((dir / "run").string());
  const Result many =
      ehlsim("impact --quiet --set grid.points=129 --set time.T_end=0.1 --out " + out,
             "env OMP_NUM_THREADS=100000 ");
  EXPECT_EQ(many.exit_code, 0) << many.err;
  EXPECT_TRUE(fs::exists(dir / "run" / "run.json"));
  for (const char* command : {"impact", "rolling"}) {
    const Result bad =
        ehlsim(std::string(command) + " --quiet --out " + out + "2", "env OMP_NUM_THREADS=abc ");
    EXPECT_EQ(bad.exit_code, 2);
    // libgomp's own warning may come first.
    EXPECT_TRUE(bad.err.ends_with(
        "ehlsim: error: OMP_NUM_THREADS = 'abc': must be a whole number of threads >= 1 (unset: "
        "ehlsim chooses them from the cores that are free)\n"))
        << bad.err;
    EXPECT_FALSE(fs::exists(dir / "run2"));
  }
}

// Under a limit of the process that the memory guard does not see, a run
// that runs out of memory said only "std::bad_alloc".  (Not in the sanitizer
// pass, SAN_SKIP of .ci/run: a sanitizer's runtime reserves terabytes of
// address space and cannot start under ulimit -v.)
TEST(Cli, RunningOutOfMemorySaysSo) {
  TempDir dir;
  const std::string reason =
      "out of memory (std::bad_alloc): this process may not allocate more, by a limit of its own "
      "(ulimit -v, a memory cgroup) or the machine's; use fewer grid.points, or raise the limit\n";
  const std::string limited = "bash -c 'ulimit -v 100000; exec \"$0\" \"$@\"' ";
  for (const char* command : {"impact --set grid.points=257", "rolling --set grid.points=513"}) {
    const Result r =
        ehlsim(std::string(command) + " --quiet --out " + quote((dir / "run").string()), limited);
    EXPECT_EQ(r.exit_code, 1) << command;
    EXPECT_TRUE(r.err.starts_with("ehlsim: error: ") && r.err.ends_with(reason)) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_TRUE(fs::is_empty(dir.path())) << "left: " << fs::directory_iterator(dir.path())->path();
  }
}

TEST(Cli, VersionAndHelp) {
  const Result version = ehlsim("--version");
  EXPECT_EQ(version.exit_code, 0);
  EXPECT_EQ(version.out.rfind(std::string("ehlsim ") + EHLSIM_VERSION + " (revision ", 0), 0u)
      << version.out;
  const Result help = ehlsim("impact --help");
  EXPECT_EQ(help.exit_code, 0);
  for (const char* text : {"--set", "--out", "--quiet", "case.M = 100  (float, > 0)",
                           "grid.points = 257  (integer, 2^k + 1 between 9 and 4097)",
                           "time.T_end = until lift-off", "solver.deformation = \"fft\""}) {
    EXPECT_NE(help.out.find(text), std::string::npos) << text;
  }
}

TEST(Cli, UsageDocumentsTheHelpVerbatim) {
  // docs/usage.md quotes `ehlsim impact --help` and `ehlsim rolling --help` in
  // full (scripts/sync_usage_help.py writes them): a new or changed option or
  // key must be documented there too.
  const std::string usage = read_file(source_dir() / "docs" / "usage.md");
  for (const std::string command : {"impact", "rolling"}) {
    const Result help = ehlsim(command + " --help");
    ASSERT_EQ(help.exit_code, 0);
    const std::string intro = "`./build/apps/ehlsim " + command +
                              " --help` (ehlsim " EHLSIM_VERSION "), verbatim:\n\n```text\n";
    const std::size_t start = usage.find(intro);
    ASSERT_NE(start, std::string::npos) << "docs/usage.md: no verbatim block for " << command;
    const std::size_t body = start + intro.size();
    EXPECT_EQ(usage.substr(body, usage.find("```\n", body) - body), help.out) << command;
  }
}

/// `ehlsim impact --quiet` on 33^2 into `run` with further options.
Result tiny_run(const fs::path& run, const std::string& options) {
  return ehlsim("impact --quiet --set grid.points=33 --set solver.coarsest_points=9 " + options +
                " --out " + quote(run.string()));
}

TEST(Cli, EveryOutputNamesTheBinaryThatWroteIt) {
  // run.json's program and fields.nc's source name the revision --version does.
  const Result version = ehlsim("--version");
  ASSERT_EQ(version.exit_code, 0);
  const std::string prefix = "ehlsim " EHLSIM_VERSION " (revision ";
  ASSERT_EQ(version.out.rfind(prefix, 0), 0u) << version.out;
  ASSERT_TRUE(version.out.ends_with(")\n")) << version.out;
  const std::string revision =
      version.out.substr(prefix.size(), version.out.size() - prefix.size() - 2);
  TempDir dir;
  ASSERT_EQ(tiny_run(dir / "run", "--set time.T_end=0.2").exit_code, 0);
  const nlohmann::json run = nlohmann::json::parse(read_file(dir / "run" / "run.json"));
  EXPECT_EQ(run.at("program").at("revision"), revision);
  EXPECT_EQ(run.at("program").at("command"), "impact");
  int ncid = -1;
  ASSERT_EQ(nc_open((dir / "run" / "fields.nc").c_str(), NC_NOWRITE, &ncid), NC_NOERR);
  std::size_t length = 0;
  ASSERT_EQ(nc_inq_attlen(ncid, NC_GLOBAL, "source", &length), NC_NOERR);
  std::string source(length, '\0');
  ASSERT_EQ(nc_get_att_text(ncid, NC_GLOBAL, "source", source.data()), NC_NOERR);
  nc_close(ncid);
  EXPECT_EQ(source + "\n", version.out);
}

TEST(Cli, AnOutNameMustLeaveRoomForTheFilesBesideIt) {
  // NAME_MAX is 255: "NAME.checkpoint.nc.part" beside the run directory
  // takes 19 bytes more than NAME.  A 250-byte name used to fail at its lock
  // file ("File name too long", exit 1), a 241-byte one at its checkpoint.
  TempDir dir;
  const fs::path longest = dir / std::string(236, 'x');
  const Result ok = tiny_run(longest, "--set time.T_end=0.2 --set output.checkpoint_every=1");
  ASSERT_EQ(ok.exit_code, 0) << ok.err;
  EXPECT_TRUE(fs::exists(longest / "checkpoint.nc"));
  const fs::path too_long = dir / std::string(237, 'x');
  const std::string message =
      "--out '" + too_long.string() +
      "': a name of 237 bytes is too long: ehlsim writes '.NAME.part-PID' and "
      "'NAME.checkpoint.nc.part' beside the run directory, so its name may have at most 236 bytes";
  expect_bad_input(ehlsim("impact --set grid.points=33 --out " + quote(too_long.string())),
                   message);
  expect_bad_input(ehlsim("rolling --set grid.points=33 --out " + quote(too_long.string())),
                   message);
  EXPECT_EQ(std::distance(fs::directory_iterator(dir.path()), fs::directory_iterator()), 1);
}

TEST(Cli, MemoryGuardRefusesAHugeGridAtOnce) {
  TempDir dir;
  const fs::path out = dir / "run";
  ehlsim::testing::expect_memory_guard_refusal("impact", out);
  EXPECT_FALSE(fs::exists(out));
  // A run that fits records the estimate and the limit.
  ASSERT_EQ(tiny_run(out, "--set body.elastic=false --set time.T_end=0.2").exit_code, 0);
  const nlohmann::json memory =
      nlohmann::json::parse(read_file(out / "run.json")).at("invocation").at("memory");
  EXPECT_GT(memory.at("estimate_mb").get<double>(), 0.0);
  EXPECT_EQ(memory.at("limit_source"), "MemAvailable");
}

TEST(Cli, TinyRun) {
  TempDir dir;
  const fs::path run = dir / "run";
  const Result r = tiny_run(run, "--set body.elastic=false --set time.T_end=0.3");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.out, "");  // --quiet: nothing but errors
  EXPECT_EQ(r.err, "");
  const std::string csv = read_file(run / "timeseries.csv");
  EXPECT_EQ(
      csv.rfind(
          "T,Delta,dDelta_dT,force,h_center,h_min,p_center,p_max,cycles,residual,attempts,work\n",
          0),
      0u);
  EXPECT_GE(std::count(csv.begin(), csv.end(), '\n'),
            3);  // header and at least 2 steps (dT = 0.09375)
  EXPECT_TRUE(fs::exists(run / "fields.nc"));
  EXPECT_TRUE(fs::exists(run / "run.json"));
  for (const auto& entry : fs::directory_iterator(run)) {
    EXPECT_NE(entry.path().extension(), ".part") << entry.path();
  }
}

TEST(Cli, RestartFromACheckpoint) {
  TempDir dir;
  const fs::path first = dir / "first";
  const fs::path second = dir / "second";
  Result r = tiny_run(first,
                      "--set body.elastic=false --set time.T_end=0.5 "
                      "--set output.checkpoint_every=2");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const fs::path checkpoint = first / "checkpoint.nc";
  ASSERT_TRUE(fs::exists(checkpoint));
  // The steps after the checkpoint, with a changed solver setting and end time.
  r = tiny_run(second,
               "--set body.elastic=false --set time.T_end=0.6 --set solver.max_cycles=30 "
               "--restart " +
                   quote(checkpoint.string()));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json run = nlohmann::json::parse(read_file(second / "run.json"));
  const int step = run.at("invocation").at("restart").at("step").get<int>();
  EXPECT_EQ(step % 2, 0);
  const std::string csv = read_file(second / "timeseries.csv");
  const std::string first_row = csv.substr(csv.find('\n') + 1);
  EXPECT_GT(std::stod(first_row), run.at("invocation").at("restart").at("T").get<double>());

  // Another case, or a file that is no checkpoint: exit 2 with the key or the file.
  expect_bad_input(
      tiny_run(dir / "third", "--set body.elastic=true --restart " + quote(checkpoint.string())),
      "body.elastic = true, but checkpoint '" + checkpoint.string() +
          "' was written with false (a restart continues the same case: only "
          "solver.*, output.*, spike.*, time.T_end and time.max_steps may change, "
          "solver.face_mean excepted)");
  // A time the checkpoint has passed (it ran one step and ended with exit 0).
  expect_bad_input(
      tiny_run(dir / "early", "--set body.elastic=false --set time.T_end=0.01 --restart " +
                                  quote(checkpoint.string())),
      fmt::format("time.T_end = 0.01: must be later than the time of checkpoint '{}', T = {:.6g}",
                  checkpoint.string(), run.at("invocation").at("restart").at("T").get<double>()));
  // Nor a cap it has reached (it ran one step and ended with exit 1).
  expect_bad_input(
      tiny_run(dir / "capped",
               "--set body.elastic=false --set time.T_end=inf --set time.max_steps=1 --restart " +
                   quote(checkpoint.string())),
      fmt::format("time.max_steps = 1: must be more than the steps of checkpoint '{}', {}",
                  checkpoint.string(), step));
  const fs::path not_a_checkpoint = second / "timeseries.csv";
  r = tiny_run(dir / "fourth",
               "--set body.elastic=false --restart " + quote(not_a_checkpoint.string()));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("cannot read checkpoint '" + not_a_checkpoint.string()), std::string::npos)
      << r.err;
  EXPECT_FALSE(fs::exists(dir / "third"));
  EXPECT_FALSE(fs::exists(dir / "fourth"));
  EXPECT_FALSE(fs::exists(dir / "capped"));
  // The default cap (4 dry lift-off times, 180 steps here), which the user did
  // not set, was named as if they had, with no way on.
  const std::string at_rest = "--set body.elastic=false --set case.M=1 --set case.L=0 ";
  ASSERT_EQ(tiny_run(dir / "long", at_rest + "--set time.T_end=30 --set output.checkpoint_every=50")
                .exit_code,
            0);
  const fs::path late = dir / "long" / "checkpoint.nc";
  expect_bad_input(tiny_run(dir / "on", at_rest + "--restart " + quote(late.string())),
                   "time.max_steps = 180 (the default): must be more than the steps of checkpoint "
                   "'" +
                       late.string() + "', 320: set a larger time.max_steps, or a time.T_end");
}

TEST(Cli, ARestartThatEndsBeforeItsNextCheckpointKeepsTheOneItResumedFrom) {
  // It removed DIR.checkpoint.nc, the file it resumed from, and published DIR
  // without a checkpoint.nc: the uninterrupted run has that checkpoint.
  TempDir dir;
  const std::string args = "--set output.checkpoint_every=4";  // lift-off 2 steps after one
  ASSERT_EQ(tiny_run(dir / "full", args).exit_code, 0);
  const fs::path resumed_from = dir / "again.checkpoint.nc";
  fs::copy_file(dir / "full" / "checkpoint.nc", resumed_from);
  Result r = tiny_run(dir / "again", args + " --restart " + quote(resumed_from.string()));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(read_file(dir / "again" / "checkpoint.nc"), read_file(dir / "full" / "checkpoint.nc"));
  EXPECT_FALSE(fs::exists(resumed_from));  // it went along
  const nlohmann::json run = nlohmann::json::parse(read_file(dir / "again" / "run.json"));
  EXPECT_EQ(run.at("files").at("checkpoint"), "checkpoint.nc");
  // Resumed from the checkpoint in DIR, into DIR: it was deleted with the earlier run.
  r = tiny_run(dir / "full",
               args + " --restart " + quote((dir / "full" / "checkpoint.nc").string()));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(read_file(dir / "full" / "checkpoint.nc"), read_file(dir / "again" / "checkpoint.nc"));
  // Without checkpoints asked for, none is published.
  r = tiny_run(dir / "none", "--restart " + quote((dir / "full" / "checkpoint.nc").string()));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_FALSE(fs::exists(dir / "none" / "checkpoint.nc"));
  EXPECT_TRUE(fs::exists(dir / "full" / "checkpoint.nc"));
  // A path with a backslash, which libnetcdf cannot open ("NetCDF: HDF error",
  // as if the file were damaged), is refused as such; by a relative link
  // without one it is read, and published as the file, not as the link.
  const fs::path odd = dir / "saved\\one.nc";
  fs::copy_file(dir / "full" / "checkpoint.nc", odd);
  expect_bad_input(tiny_run(dir / "odd", args + " --restart " + quote(odd.string())),
                   "cannot read checkpoint '" + odd.string() +
                       "': the path holds a backslash, which the NetCDF library reads as a "
                       "directory separator: rename it, or give it by a link whose path has none");
  fs::create_symlink(odd.filename(), dir / "plain.nc");
  r = tiny_run(dir / "linked", args + " --restart " + quote((dir / "plain.nc").string()));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_FALSE(fs::is_symlink(dir / "linked" / "checkpoint.nc"));
  EXPECT_EQ(read_file(dir / "linked" / "checkpoint.nc"), read_file(odd));
}

TEST(Cli, RestartRefusesADamagedCheckpoint) {
  // The probes of issue 10: 16 flipped bytes, T = NaN, step = INT_MAX.
  TempDir dir;
  const std::string options = "--set body.elastic=false --set time.T_end=0.5 ";
  ASSERT_EQ(tiny_run(dir / "first", options + "--set output.checkpoint_every=2").exit_code, 0);
  const fs::path good = dir / "first" / "checkpoint.nc";
  const fs::path bad = dir / "checkpoint.nc";
  const auto restart = [&] {
    return tiny_run(dir / "second", options + "--restart " + quote(bad.string()));
  };
  const std::string prefix = "checkpoint " + bad.string() + ": ";

  fs::copy_file(good, bad);
  const ehlsim::Field rhoH = ehlsim::read_checkpoint(good).state.rhoH;
  ehlsim::testing::flip_16_bytes_of(bad, rhoH, rhoH.size() / 2);
  expect_bad_input(restart(), prefix +
                                  "checksum mismatch: the file is corrupt (its data do not match "
                                  "the CRC-32 it was written with)");
  fs::copy_file(good, bad, fs::copy_options::overwrite_existing);
  ehlsim::testing::rewrite_attribute(bad, "T", std::numeric_limits<double>::quiet_NaN());
  expect_bad_input(restart(), prefix + "field 'T' is not finite (nan)");
  fs::copy_file(good, bad, fs::copy_options::overwrite_existing);
  ehlsim::testing::rewrite_attribute(bad, "step", std::numeric_limits<int>::max());
  const Result r = restart();
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.err,
            "ehlsim: error: " + prefix + "field 'step' = 2147483647: must be in [1, 10000000]\n")
      << r.err;
  EXPECT_FALSE(fs::exists(dir / "second"));
}

/// Exit 2 and one line "ehlsim: error: <prefix>the NetCDF/HDF5 library
/// crashed reading it (SIGSEGV): the file is damaged"; AddressSanitizer (the
/// sanitizer build) sees HDF5's bad memcpy first and ends the child with exit
/// status 1 instead.
void expect_library_crash(const Result& r, const std::string& prefix) {
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.out, "");
  const std::string crashed =
      "ehlsim: error: " + prefix + "the NetCDF/HDF5 library crashed reading it (";
  const std::string damaged = "): the file is damaged\n";
  ASSERT_TRUE(r.err.starts_with(crashed) && r.err.ends_with(damaged)) << r.err;
  const std::string how =
      r.err.substr(crashed.size(), r.err.size() - crashed.size() - damaged.size());
  EXPECT_TRUE(how == "SIGSEGV" || how == "exit status 1") << r.err;
}

TEST(Cli, FilesHdf5CrashesOnAreBadInputNotACrash) {
  // HDF5 1.10.8 segfaults in H5HG_read on these (docs/validation.md): before,
  // both commands died with exit 139; the child process that reads first dies now.
  TempDir dir;
  const fs::path checkpoint = library_crash("checkpoint-v9-hdf5-H5HG_read-segv.nc");
  expect_library_crash(tiny_run(dir / "run", "--restart " + quote(checkpoint.string())),
                       "cannot read checkpoint '" + checkpoint.string() + "': ");
  EXPECT_FALSE(fs::exists(dir / "run"));

  const fs::path run = dir / "finished";
  fs::create_directories(run);
  write_file(run / "run.json", ehlsim::testing::minimal_run_json());
  fs::copy_file(library_crash("fields-hdf5-H5HG_read-segv.nc"), run / "fields.nc");
  expect_library_crash(ehlsim("spike --quiet " + quote(run.string())),
                       "cannot read '" + (run / "fields.nc").string() + "': ");
  EXPECT_FALSE(fs::exists(run / "spike_snapshots.csv"));
}

TEST(Cli, BadSpikeKeys) {
  expect_bad_input(
      ehlsim("impact --set spike.filter=median"),
      "spike.filter = \"median\": must be one of \"butterworth\", \"gaussian\", \"none\" (--set)");
  expect_bad_input(ehlsim("impact --set spike.smoothing_points=0"),
                   "spike.smoothing_points = 0: must be in [1, 2147483647] (--set)");
  expect_bad_input(ehlsim("impact --set spike.cutoff_meshes=0.2"),
                   "spike.cutoff_meshes = 0.2: must be > 2 spike.resample_meshes = 0.25 (the "
                   "shortest wave the resampled profile carries) (--set)");
  expect_bad_input(ehlsim("impact --set spike.min_height=2"),
                   "spike.min_height = 2: must be in [0, 1] (--set)");
}

TEST(Cli, SpikeOnABadRunDirectory) {
  TempDir dir;
  const std::string missing = (dir / "missing").string();
  expect_bad_input(ehlsim("spike --quiet " + quote(missing)),
                   "run directory '" + missing + "' does not exist or is not a directory");
  // An empty RUN_DIR (an unset shell variable) and a file as RUN_DIR (both
  // were named as the --out it defaults to).
  expect_bad_input(ehlsim("spike --quiet ''"),
                   "run directory '' does not exist or is not a directory");
  const std::string file = write_file(dir / "run.json", "{}").string();
  expect_bad_input(ehlsim("spike --quiet " + quote(file)),
                   "run directory '" + file + "' does not exist or is not a directory");
  const std::string empty = (dir / "empty").string();
  fs::create_directories(empty);
  expect_bad_input(ehlsim("spike --quiet " + quote(empty)),
                   "cannot read '" + empty +
                       "/run.json': not a complete ehlsim run directory "
                       "(run.json is written last, when the run has finished)");
  // A directory beside which no lock can be made: exit 1, "cannot create
  // lock file '/proc/.PID.lock'", for what is no run directory.
  expect_bad_input(ehlsim("spike --quiet /proc/self"),
                   "cannot read '/proc/self/run.json': not a complete ehlsim run directory "
                   "(run.json is written last, when the run has finished)");
  // A run.json that is no regular file: a FIFO (opening it waited for ever
  // for a writer) and a directory (the parser's error named no file).
  for (const char* kind : {"fifo", "directory"}) {
    const fs::path odd = dir / kind;
    fs::create_directories(odd);
    if (std::string(kind) == "fifo") {
      ASSERT_EQ(::mkfifo((odd / "run.json").c_str(), 0644), 0);
    } else {
      fs::create_directory(odd / "run.json");
    }
    expect_bad_input(ehlsim("spike --quiet " + quote(odd.string())),
                     "cannot read '" + (odd / "run.json").string() +
                         "': not a complete ehlsim run directory (run.json is written last, when "
                         "the run has finished)");
  }
  // A run.json without the run's spike settings was analysed with the defaults.
  write_file(dir / "empty" / "run.json", R"({"parameters": {"time": {"Delta0": 1.0, "V0": 1.0}}})");
  expect_bad_input(ehlsim("spike --quiet " + quote(empty)),
                   "cannot read '" + empty +
                       "/run.json': no table parameters.spike (the run's spike settings, which "
                       "every run of ehlsim impact records)");
  write_file(dir / "empty" / "run.json", R"({"program": {"command": 5}})");
  expect_bad_input(
      ehlsim("spike --quiet " + quote(empty)),
      "cannot read '" + empty + "/run.json': program.command is 5, not the name of a command");
  write_file(dir / "empty" / "run.json", R"({"program": ["impact"]})");
  expect_bad_input(ehlsim("spike --quiet " + quote(empty)),
                   "cannot read '" + empty + "/run.json': program is [\"impact\"], not a table");
  // ... or one of the settings (merge_patch removes a key set to null).
  write_file(
      dir / "empty" / "run.json",
      ehlsim::testing::minimal_run_json({{"parameters", {{"spike", {{"min_height", nullptr}}}}}}));
  expect_bad_input(ehlsim("spike --quiet " + quote(empty)),
                   "cannot read '" + empty +
                       "/run.json': parameters.spike has no min_height (every run of ehlsim impact "
                       "records each spike setting)");
  // ... or one that is null or a table: shown as the text "null", quoted.
  for (const auto& [odd, shown] :
       {std::pair{nlohmann::json(nullptr), std::string("null")},
        std::pair{nlohmann::json{{"a", 1}}, std::string(R"({"a":1})")}}) {
    nlohmann::json run = nlohmann::json::parse(ehlsim::testing::minimal_run_json());
    run["parameters"]["spike"]["filter"] = odd;
    write_file(dir / "empty" / "run.json", run.dump());
    expect_bad_input(ehlsim("spike --quiet " + quote(empty)),
                     "cannot read '" + empty + "/run.json': parameters.spike.filter is " + shown +
                         ", not the value of a setting (a number or a text)");
  }
  // A link loop as RUN_DIR was named as the --out it defaults to.
  fs::create_symlink("loop2", dir / "loop1");
  fs::create_symlink("loop1", dir / "loop2");
  expect_bad_input(
      ehlsim("spike --quiet " + quote((dir / "loop1").string())),
      "run directory '" + (dir / "loop1").string() + "' does not exist or is not a directory");
  // A run.json without fields.nc: the NetCDF error, on one line.
  const std::string kMinimalRun = ehlsim::testing::minimal_run_json();
  write_file(dir / "empty" / "run.json", kMinimalRun);
  const Result r = ehlsim("spike --quiet " + quote(empty));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.err.rfind("ehlsim: error: cannot read '" + empty + "/fields.nc'", 0), 0u) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  expect_bad_input(ehlsim("spike --quiet " + quote(empty) + " --set case.M=3"),
                   "--set 'case.M=3': only spike.* keys apply to an analysis of a finished run");
  // A bad spike setting is named where it was given: run.json, or --set.
  write_file(dir / "empty" / "run.json",
             ehlsim::testing::minimal_run_json({{"parameters", {{"spike", {{"filter", "x"}}}}}}));
  expect_bad_input(ehlsim("spike --quiet " + quote(empty)),
                   "spike.filter = \"x\": must be one of \"butterworth\", \"gaussian\", "
                   "\"none\" (parameters of '" +
                       empty + "/run.json')");
  // ... also a value that is no TOML value (it was told "(--set)").
  write_file(dir / "empty" / "run.json",
             ehlsim::testing::minimal_run_json(
                 {{"parameters", {{"spike", {{"smoothing_points", 18446744073709551615U}}}}}}));
  expect_bad_input(ehlsim("spike --quiet " + quote(empty)),
                   "spike.smoothing_points = 18446744073709551615: is beyond the range of an "
                   "integer (magnitudes up to 9223372036854775807; a larger number is written "
                   "with an exponent, such as 1e30) (parameters of '" +
                       empty + "/run.json')");
  // A setting too small for a double was read as 0 and analysed with it.
  std::string tiny = ehlsim::testing::minimal_run_json(
      {{"parameters", {{"spike", {{"min_prominence", 12345.0}}}}}});
  tiny.replace(tiny.find("12345.0"), 7, "1e-400");
  write_file(dir / "empty" / "run.json", tiny);
  expect_bad_input(ehlsim("spike --quiet " + quote(empty)),
                   "cannot read '" + empty +
                       "/run.json': parameters.spike.min_prominence = 1e-400 is too small for a "
                       "double, which would read it as 0 (the smallest positive double is "
                       "4.94066e-324)");
  write_file(dir / "empty" / "run.json", kMinimalRun);
  expect_bad_input(ehlsim("spike --quiet " + quote(empty) + " --set spike.filter=y"),
                   "spike.filter = \"y\": must be one of \"butterworth\", \"gaussian\", "
                   "\"none\" (--set)");
  // A rolling run has a run.json and a fields.nc, but no spike to track.
  const fs::path rolling = dir / "rolling";
  ASSERT_EQ(
      ehlsim("rolling --quiet --set grid.points=33 --out " + quote(rolling.string())).exit_code, 0);
  expect_bad_input(ehlsim("spike --quiet " + quote(rolling.string())),
                   "cannot analyse '" + (rolling / "run.json").string() +
                       "': a run of `ehlsim rolling`; ehlsim spike analyses runs of `ehlsim "
                       "impact`");
}

TEST(Cli, SpikeSaysWhyRunJsonCannotBeRead) {
  // Every failure to open run.json was "not a complete ehlsim run directory".
  // A missing permission is the user's input too (exit 2), said as such.
  // Root reads anything, so as root the analysis runs as the user nobody.
  TempDir dir;
  const fs::path run = dir / "run";
  ASSERT_EQ(tiny_run(run, "--set time.T_end=0.2").exit_code, 0);
  std::string launcher;
  if (geteuid() == 0) {
    constexpr uid_t kNobody = 65534;  // Debian's user and group nobody
    for (const fs::path& path : {dir.path(), run, run / "run.json"})
      ASSERT_EQ(::chown(path.c_str(), kNobody, kNobody), 0) << std::strerror(errno);
    launcher = "setpriv --reuid=65534 --regid=65534 --clear-groups ";
    if (ehlsim("--version", launcher).exit_code != 0)
      GTEST_SKIP() << "the user nobody cannot run this build's ehlsim";
  }
  fs::permissions(run / "run.json", fs::perms::none);
  expect_bad_input(ehlsim("spike --quiet " + quote(run.string()), launcher),
                   "cannot read '" + (run / "run.json").string() + "': Permission denied");
  EXPECT_FALSE(fs::exists(run / "spike_snapshots.csv"));
  EXPECT_EQ(std::distance(fs::directory_iterator(dir.path()), fs::directory_iterator()), 1)
      << "no staging directory or lock left beside the run";
}

TEST(Cli, SpikeRefusesAFieldsFileNoRunWrites) {
  // Values a run never writes gave exit 0 with NaN or inf in spike.csv.
  TempDir dir;
  const fs::path run = dir / "run";
  ASSERT_EQ(
      ehlsim("impact --quiet --set grid.points=33 --set time.T_end=1 --out " + quote(run.string()))
          .exit_code,
      0);
  const fs::path fields = run / "fields.nc";
  const fs::path good = dir / "good.nc";
  fs::copy_file(fields, good);
  const std::string prefix = "cannot use '" + fields.string() + "': snapshot 0 ";
  const double nan = std::numeric_limits<double>::quiet_NaN();
  ehlsim::testing::rewrite_value(fields, "P", {0, 10, 12}, nan);
  expect_bad_input(
      ehlsim("spike --quiet " + quote(run.string())),
      prefix +
          "(T = 1.03125) has the pressure nan at point (12, 10) (a run writes finite pressures "
          ">= 0)");
  fs::copy_file(good, fields, fs::copy_options::overwrite_existing);
  ehlsim::testing::rewrite_value(fields, "P", {0, 3, 4}, -5.0);
  expect_bad_input(ehlsim("spike --quiet " + quote(run.string())),
                   prefix +
                       "(T = 1.03125) has the pressure -5 at point (4, 3) (a run writes "
                       "finite pressures >= 0)");
  fs::copy_file(good, fields, fs::copy_options::overwrite_existing);
  ehlsim::testing::rewrite_value(fields, "time", {0}, nan);
  expect_bad_input(ehlsim("spike --quiet " + quote(run.string())),
                   prefix +
                       "has time nan (the times of a run are finite and increasing; the one "
                       "before is -inf)");
  // A finite pressure no run reaches: the filter's sums overflowed to -nan, with exit 0.
  fs::copy_file(good, fields, fs::copy_options::overwrite_existing);
  ehlsim::testing::rewrite_value(fields, "P", {0, 16, 16}, 1e308);
  expect_bad_input(ehlsim("spike --quiet " + quote(run.string())),
                   prefix + "(T = 1.03125) has the pressure 1e+308 (no run's is above 1e+100)");
  // No snapshot at all (time of length 0): CSV headers alone, with exit 0.
  {
    ehlsim::FieldWriter empty(fields, ehlsim::Grid2D(33, 1.5), nlohmann::json::object());
    empty.commit();
  }
  expect_bad_input(ehlsim("spike --quiet " + quote(run.string())),
                   "cannot use '" + fields.string() +
                       "': it holds no snapshot (time has length 0; every run stores at least its "
                       "last step)");
  EXPECT_FALSE(fs::exists(run / "spike_snapshots.csv"));
  // A start in run.json that gives no dry contact (Delta0 = 1e308 failed with exit 1).
  fs::copy_file(good, fields, fs::copy_options::overwrite_existing);
  nlohmann::json edited = nlohmann::json::parse(read_file(run / "run.json"));
  edited["parameters"]["time"]["Delta0"] = 1e308;
  write_file(run / "run.json", edited.dump());
  const Result far = ehlsim("spike --quiet " + quote(run.string()));
  EXPECT_EQ(far.exit_code, 2) << far.err;
  EXPECT_EQ(far.err.rfind("ehlsim: error: cannot use '" + (run / "run.json").string() +
                              "': parameters.time Delta0 = 1e+308 and V0 = 1 give no dry "
                              "contact to compare with (",
                          0),
            0u)
      << far.err;
}

TEST(Cli, AnInputTheMachineCannotReadIsAFailureNotBadInput) {
  // /proc/self/mem reads with EIO at its first byte, as a failing disk does.
  // Its first bytes were taken for another format ("not a NetCDF-4 file",
  // exit 2, bad input); an I/O error is the machine's failure: exit 1.
  TempDir dir;
  const fs::path run = dir / "run";
  ASSERT_EQ(tiny_run(run, "--set time.T_end=0.2").exit_code, 0);
  fs::remove(run / "fields.nc");
  fs::create_symlink("/proc/self/mem", run / "fields.nc");
  expect_failure(ehlsim("spike --quiet " + quote(run.string())),
                 "cannot read '" + (run / "fields.nc").string() + "': Input/output error");
  EXPECT_FALSE(fs::exists(run / "spike_snapshots.csv"));
  expect_failure(ehlsim("impact --quiet --set grid.points=33 --restart /proc/self/mem --out " +
                        quote((dir / "again").string())),
                 "cannot read checkpoint '/proc/self/mem': Input/output error");
  EXPECT_FALSE(fs::exists(dir / "again"));
  // run.json: libstdc++'s "basic_filebuf::underflow error reading the file", no path named.
  fs::remove(run / "fields.nc");
  fs::remove(run / "run.json");
  fs::create_symlink("/proc/self/mem", run / "run.json");
  expect_failure(ehlsim("spike --quiet " + quote(run.string())),
                 "cannot read '" + (run / "run.json").string() + "': Input/output error");
}

TEST(Cli, SpikeFilesGoIntoTheRunOrADirectoryOfTheirOwn) {
  TempDir dir;
  const fs::path run = dir / "run", other = dir / "other";
  ASSERT_EQ(tiny_run(run, "--set time.T_end=0.2").exit_code, 0);
  ASSERT_EQ(tiny_run(other, "--set time.T_end=0.2").exit_code, 0);
  const std::string where =
      " go into the run directory (the default) or a directory of their own, such as RUN/gauss";
  // Beside another run's results they would describe a run that is not there.
  expect_bad_input(
      ehlsim("spike --quiet " + quote(run.string()) + " --out " + quote(other.string())),
      "--out '" + other.string() +
          "' is another run's directory (it holds a "
          "run.json): the spike files of '" +
          run.string() + "'" + where);
  // A directory that holds the run would be made anew as a whole.
  const std::string parent = (run / "..").string();
  expect_bad_input(ehlsim("spike --quiet " + quote(run.string()) + " --out " + quote(parent)),
                   "--out '" + parent + "' holds the run directory '" + run.string() +
                       "': the spike files" + where);
  EXPECT_FALSE(fs::exists(other / "spike_profiles.csv"));
  ASSERT_EQ(
      ehlsim("spike --quiet " + quote(run.string()) + " --out " + quote((run / "gauss").string()))
          .exit_code,
      0);
  EXPECT_TRUE(fs::exists(run / "gauss" / "spike_profiles.csv"));
}

TEST(Cli, SpikeFilesOfARun) {
  TempDir dir;
  const fs::path run = dir / "run";
  const Result r = tiny_run(run, "--set time.T_end=0.4 --set output.snapshot_every=2");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string spike = read_file(run / "spike.csv");
  EXPECT_EQ(spike.rfind("T,R_s,P_s,V_s,A_dry,X_s,P_xs\n", 0), 0u);
  const std::string series = read_file(run / "timeseries.csv");
  EXPECT_EQ(std::count(spike.begin(), spike.end(), '\n'),
            std::count(series.begin(), series.end(), '\n'));
  const Result offline = ehlsim("spike --quiet " + quote(run.string()));
  ASSERT_EQ(offline.exit_code, 0) << offline.err;
  for (const char* name : {"spike_snapshots.csv", "spike_profiles.csv", "axis_profiles.csv"}) {
    EXPECT_TRUE(fs::exists(run / name)) << name;
  }
  EXPECT_EQ(read_file(run / "spike_snapshots.csv").rfind("T,R_s,P_s,V_s,A_dry,X_s,P_xs\n", 0), 0u);
  for (const auto& entry : fs::directory_iterator(run)) {
    EXPECT_NE(entry.path().extension(), ".part") << entry.path();
  }
}

TEST(Cli, ASpikeAnalysisOfAWavySurfaceSaysItMixesDirections) {
  // The analysis sorts P by R alone (docs/model.md, section 10); with
  // waviness P depends on the direction too, and R_s mixes them.
  TempDir dir;
  const fs::path wavy = dir / "wavy";
  ASSERT_EQ(tiny_run(wavy,
                     "--set time.T_end=0.2 --set surface.waviness_amplitude=0.05 "
                     "--set surface.waviness_wavelength=0.5 --set surface.waviness_angle_deg=30")
                .exit_code,
            0);
  const std::string note =
      "the waviness (surface.waviness_amplitude = 0.05) makes the pressure depend on the "
      "direction, while the spike analysis (spike.csv, ehlsim spike) sorts the pressure of X, Y "
      ">= 0 by the radius R alone: its R_s and P_s are of that mixture of directions; "
      "axis_profiles.csv (ehlsim spike) and fields.nc hold the pressure itself";
  const auto warnings_of = [](const fs::path& run) {
    return nlohmann::json::parse(read_file(run / "run.json")).at("results").at("warnings");
  };
  EXPECT_EQ(warnings_of(wavy), nlohmann::json::array({note}));
  const Result analysis = ehlsim("spike " + quote(wavy.string()));
  ASSERT_EQ(analysis.exit_code, 0) << analysis.err;
  EXPECT_EQ(analysis.err, "ehlsim: warning: " + note + "\n");
  // A smooth ball's run and analysis say nothing of the kind.
  const fs::path smooth = dir / "smooth";
  ASSERT_EQ(tiny_run(smooth, "--set time.T_end=0.2").exit_code, 0);
  EXPECT_TRUE(warnings_of(smooth).empty());
  EXPECT_EQ(ehlsim("spike " + quote(smooth.string())).err, "");
}

TEST(Cli, StudyRejectsBadInputBeforeAnyRun) {
  TempDir dir;
  const fs::path out = dir / "study";
  expect_bad_input(
      ehlsim("study --grid 100 --out " + quote(out.string())),
      "--grid = 100: must be 2^k + 1 between 9 and 4097 (the points per side of every impact "
      "case)");
  expect_bad_input(
      ehlsim("study --grid 33 --rolling-grid 200 --out " + quote(out.string())),
      "--rolling-grid = 200: must be 2^k + 1 between 9 and 4097 (the points per side of the "
      "rolling runs)");
  const int cores = available_cores();
  for (const int jobs : {0, cores + 1, 1000}) {
    expect_bad_input(
        ehlsim("study --grid 33 --jobs " + std::to_string(jobs) + " --out " + quote(out.string())),
        "--jobs = " + std::to_string(jobs) + ": must be in [1, " + std::to_string(cores) +
            "] (the cores of this machine; each case runs on one)");
  }
  expect_bad_input(ehlsim("study --grid 33 --set case.M=3 --out " + quote(out.string())),
                   "--set 'case.M=3': the study sets case.M itself in every case (M = 100, 50, "
                   "20, 10 with L = 10); --set applies the other keys to every case");
  // A key no case knows is unknown, whichever section it names.
  expect_bad_input(ehlsim("study --grid 33 --set case.bogus=1 --out " + quote(out.string())),
                   "unknown key 'case.bogus' (known keys in [case]: M, L, lambda_bar, alpha_bar) "
                   "(--set)");
  // A Roelands law's own z would set another L in every case.
  expect_bad_input(
      ehlsim("study --grid 33 --set lubricant.z=0.6 --out " + quote(out.string())),
      "--set 'lubricant.z=0.6': the study sets lubricant.z itself in every case (the Roelands "
      "index from L = 10); --set applies the other keys to every case");
  expect_bad_input(
      ehlsim("study --grid 33 --set output.snapshot_every=1 --out " + quote(out.string())),
      "--set 'output.snapshot_every=1': the study sets output.snapshot_every itself in every case "
      "(the snapshots of the paper's figures); --set applies the other keys to every case");
  // A case directory with a file of the user's is refused before any case runs.
  fs::create_directories(out / "M100");
  write_file(out / "M100" / "notes.txt", "mine");
  expect_bad_input(ehlsim("study --grid 33 --no-plots --out " + quote(out.string())),
                   "case M100: --out '" + (out / "M100").string() +
                       "' is not empty and holds no ehlsim run.json: ehlsim writes only into a "
                       "new or empty directory or over an earlier ehlsim run; choose another "
                       "--out, or move the files yourself");
  EXPECT_FALSE(fs::exists(out / "logs"));
  fs::remove_all(out);
  // A run directory is no study directory.
  ASSERT_EQ(tiny_run(dir / "run", "--set time.T_end=0.1").exit_code, 0);
  expect_bad_input(ehlsim("study --grid 33 --no-plots --out " + quote((dir / "run").string())),
                   "--out '" + (dir / "run").string() +
                       "' holds a run.json: it is a run directory, not a study's; choose another "
                       "--out");
  fs::create_directory_symlink("loopB", dir / "loopA");
  fs::create_directory_symlink("loopA", dir / "loopB");
  const std::string loop = (dir / "loopA").string();
  expect_bad_input(ehlsim("study --grid 33 --no-plots --out " + quote(loop)),
                   "--out '" + loop + "': too many levels of symbolic links (a loop?)");
  // A loop in a parent of --out too, for every mode that writes a directory.
  const std::string below = loop + "/run";
  for (const std::string& command :
       std::vector<std::string>{"study --grid 33 --no-plots", "impact --quiet", "rolling --quiet",
                                "spike " + quote(out.string())})
    expect_bad_input(ehlsim(command + " --out " + quote(below)),
                     "--out '" + below + "': too many levels of symbolic links (a loop?)");
  expect_bad_input(
      ehlsim("study --grid 33 --python /nonexistent/python3 --out " + quote(out.string())),
      "--python '/nonexistent/python3': No such file or directory (give a Python 3 "
      "with numpy and matplotlib, or --no-plots)");
  // A directory is no interpreter or script (a directory passes access(X_OK)).
  expect_bad_input(ehlsim("study --grid 33 --python /etc --out " + quote(out.string())),
                   "--python '/etc': not a regular file (give a Python 3 with numpy and "
                   "matplotlib, or --no-plots)");
  expect_bad_input(ehlsim("study --grid 33 --plot-script /etc --out " + quote(out.string())),
                   "--plot-script '/etc': not a regular file");
  expect_bad_input(
      ehlsim("study --grid 33 --set spike.filter=median --out " + quote(out.string())),
      "spike.filter = \"median\": must be one of \"butterworth\", \"gaussian\", \"none\" (--set)");
  // A memory limit no case fits: refused before the first case starts, not
  // four failed cases and a study that ran its rolling contacts anyway.
  const Result tight =
      ehlsim("study --grid 33 --set solver.memory_limit_mb=1 --out " + quote(out.string()));
  EXPECT_EQ(tight.exit_code, 2) << tight.err;
  EXPECT_NE(tight.err.find("ehlsim: error: case M100: grid.points = 33: the run needs about "),
            std::string::npos)
      << tight.err;
  EXPECT_NE(tight.err.find("more than the limit solver.memory_limit_mb = 1"), std::string::npos)
      << tight.err;
  EXPECT_FALSE(fs::exists(out));
}

TEST(Cli, StudySetAppliesToEveryCase) {
  TempDir dir;
  const fs::path out = dir / "study";
  const Result r = ehlsim(
      "study --grid 33 --rolling-grid 65 --no-plots --set time.T_end=0.2 --set "
      "solver.coarsest_points=9 --set lubricant.ph_star=0.5e9 --set "
      "lubricant.density=dowson-higginson --out " +
      quote(out.string()));
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  for (const char* M : {"M10", "M20", "M50", "M100"}) {
    const nlohmann::json run = nlohmann::json::parse(read_file(out / M / "run.json"));
    EXPECT_EQ(run.at("parameters").at("time").at("T_end").get<double>(), 0.2) << M;
    EXPECT_EQ(run.at("parameters").at("solver").at("coarsest_points").get<int>(), 9) << M;
    EXPECT_EQ(run.at("parameters").at("lubricant").at("density"), "dowson-higginson") << M;
    EXPECT_EQ(run.at("results").at("outcome").get<std::string>(), "t_end") << M;
  }
  // The rolling runs get the lubricant (the same on both sides of the
  // similarity), not the impact's solver settings: their own coarsest grid.
  for (const char* M : {"rolling_M20", "rolling_M100"}) {
    const nlohmann::json run = nlohmann::json::parse(read_file(out / M / "run.json"));
    EXPECT_EQ(run.at("parameters").at("lubricant").at("density"), "dowson-higginson") << M;
    EXPECT_EQ(run.at("parameters").at("solver").at("coarsest_points").get<int>(), 17) << M;
    EXPECT_EQ(run.at("parameters").at("grid").at("points").get<int>(), 65) << M;
  }
}

/// The whole study on a 33^2 grid (about 3 s): four impacts, their spike
/// files, the two rolling runs of the similarity figure (65^2), the dry
/// reference, and the figures when Debian's Python has matplotlib.
TEST(Cli, AStudysFailedCaseIsReportedWithItsError) {
  // On 9^2 the rolling films go negative.  The case's log has its progress
  // lines (stdout) and its error (stderr): the error must come last, since
  // the study reports the log's last line as the reason.
  TempDir dir;
  const fs::path out = dir / "study";
  const Result r =
      ehlsim("study --grid 9 --rolling-grid 9 --no-plots --out " + quote(out.string()));
  EXPECT_EQ(r.exit_code, 1) << r.out << r.err;
  EXPECT_NE(r.out.find("  FAILED   rolling M = 20 after "), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("(exit 1): ehlsim: error: the film is negative"), std::string::npos)
      << r.out;
  const std::string log = read_file(out / "logs" / "rolling_M20.log");
  EXPECT_NE(log.find(" cycle "), std::string::npos) << log;
  EXPECT_GT(log.rfind("ehlsim: error: "), log.rfind(" cycle ")) << log;
}

TEST(Cli, TinyStudy) {
  TempDir dir;
  const fs::path out = dir / "study";
  const bool with_plots =
      std::system("/usr/bin/python3 -c 'import numpy, matplotlib' > /dev/null 2>&1") == 0;
  const Result r = ehlsim("study --grid 33 --rolling-grid 65 --out " + quote(out.string()) +
                          (with_plots ? "" : " --no-plots"));
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  const std::string summary = read_file(out / "study.json");
  for (const char* M : {"M10", "M20", "M50", "M100"}) {
    SCOPED_TRACE(M);
    for (const char* file : {"timeseries.csv", "spike.csv", "fields.nc", "run.json",
                             "spike_snapshots.csv", "spike_profiles.csv", "axis_profiles.csv"}) {
      EXPECT_TRUE(fs::exists(out / M / file)) << file;
    }
    EXPECT_NE(summary.find(std::string("\"dir\": \"") + M + "\""), std::string::npos);
  }
  for (const char* M : {"rolling_M20", "rolling_M100"}) {
    for (const char* file : {"run.json", "profile_x.csv"}) {
      EXPECT_TRUE(fs::exists(out / M / file)) << M << " " << file;
    }
    EXPECT_NE(summary.find(std::string("\"dir\": \"") + M + "\""), std::string::npos) << M;
  }
  EXPECT_NE(summary.find("\"command\": \"rolling\""), std::string::npos) << summary;
  EXPECT_EQ(summary.find("\"exit_code\": 1"), std::string::npos) << summary;
  EXPECT_EQ(read_file(out / "dry.csv").rfind("T,A_dry\n", 0), 0u);
  if (!with_plots) GTEST_SKIP() << "/usr/bin/python3 without numpy/matplotlib: figures not tried";
  for (const char* figure :
       {"fig1", "fig2", "fig3", "fig4", "fig5", "fig6", "histories", "similarity"}) {
    EXPECT_TRUE(fs::exists(out / "figures" / (std::string(figure) + ".png"))) << figure;
    EXPECT_TRUE(fs::exists(out / "figures" / (std::string(figure) + ".csv"))) << figure;
  }
  // Strict JSON: a value the script could not compute is null, not a bare NaN.
  nlohmann::json figures;
  EXPECT_NO_THROW(figures = nlohmann::json::parse(read_file(out / "figures" / "summary.json")));
  EXPECT_TRUE(figures.contains("cases")) << figures;
  // Cases stopped by time.T_end have none of the snapshots of figures 1-4: the
  // script draws the rest and fails (the study exited 0 without them), and
  // the earlier figures stay.
  const Result short_runs =
      ehlsim("study --grid 33 --rolling-grid 65 --set time.T_end=0.5 --out " + quote(out.string()));
  EXPECT_EQ(short_runs.exit_code, 1) << short_runs.out << short_runs.err;
  EXPECT_NE(short_runs.out.find("figure script failed (exit 1): figures 1-2: no snapshot of M = "),
            std::string::npos)
      << short_runs.out;
  EXPECT_TRUE(fs::exists(out / "figures" / "fig1.png"));
}

TEST(Cli, RunEchoesTheParameters) {
  TempDir dir;
  const Result r = ehlsim(
      "impact --set grid.points=33 --set solver.coarsest_points=9 "
      "--set body.elastic=false --set time.T_end=0.1 --set case.M=20 --out " +
      quote((dir / "run").string()));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("M = 20, L = 10"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("33^2"), std::string::npos) << r.out;
}

}  // namespace
