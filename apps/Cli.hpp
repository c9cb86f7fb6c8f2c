#pragma once
// What the subcommands of ehlsim share on the command line: the exit codes,
// the report on stdout, errors and warnings on stderr, and the options of a
// simulation command (apps/Cli.cpp).
#include <fmt/format.h>

#include <CLI/CLI.hpp>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <string_view>
#include <type_traits>
#include <utility>
#include <vector>

namespace cli {

inline constexpr int kExitOk = 0;
inline constexpr int kExitFailure = 1;
inline constexpr int kExitBadInput = 2;

/// The environment variable by which `ehlsim study` gives its cases its own
/// process id: a case whose parent it still is ends with the study (SIGTERM:
/// a checkpoint and the resume line in its log), as `kill -9` of the study
/// left the cases running to publish after it.
inline constexpr const char* kStudyPidVariable = "EHLSIM_STUDY_PID";

[[nodiscard]] std::string printable(std::string_view text);  // below, for shown()

/// Writes `text` to stdout.  A write that fails because the reader went away
/// (`ehlsim study | head -3`) or stdout is closed is not a failure of the
/// command: the rest of the report is lost, the run goes on, and the exit
/// code tells what it left on disk (SIGPIPE is ignored: apps/ehlsim.cpp).
void write_out(std::string_view text);

/// A text argument of print_out made printable, as print_error does (a run
/// directory named with a C1 control reached the terminal raw, a newline of
/// it broke the report's line); any other as it is.
template <typename T>
decltype(auto) shown(const T& arg) {
  if constexpr (std::is_convertible_v<const T&, std::string_view>)
    return printable(std::string_view(arg));
  else
    return (arg);
}

/// Text for stdout: what a command reports as it goes (the case, a study's
/// progress, the summary), its text arguments through shown, through write_out.
template <typename... Args>
void print_out(fmt::format_string<Args...> format, Args&&... args) {
  write_out(fmt::format(fmt::runtime(fmt::string_view(format)), shown(args)...));
}

/// "ehlsim: error: <message>" as one line on stderr, after what stdout holds
/// so far (as print_warnings).  Words longer than any
/// path (a runaway value that reached the message unshortened, e.g. through
/// CLI11) are shortened like echo_input (config/Parameters.hpp) does.
void print_error(std::string_view message);

/// What failed, for the one line of a failed command: `e.what()`, except for
/// an allocation that failed, whose what() is only "std::bad_alloc" (257^2
/// under `ulimit -v 100000` said so after step 80).
[[nodiscard]] std::string failure_reason(const std::exception& e);

/// "ehlsim: warning: <line>" on stderr for each of `warnings` (what a finished
/// run's user should know about its result), after what stdout holds so far,
/// also when both go to one pipe.
void print_warnings(const std::vector<std::string>& warnings);

/// The CONFIG argument of a command: none when empty (the built-in case).
inline std::optional<std::filesystem::path> config_path(const std::string& argument) {
  if (argument.empty()) return std::nullopt;
  return std::filesystem::path(argument);
}

/// The options every simulation command has: [CONFIG], -o/--out DIR,
/// --set KEY=VALUE (repeatable), -q/--quiet; `what_out` lists the files.
struct CaseOptions {
  std::string config_file;  ///< "" = the built-in default case
  std::string out_dir;
  std::vector<std::string> overrides;
  bool quiet = false;
};
void add_case_options(CLI::App& command, CaseOptions& options, const std::string& default_case,
                      const std::string& what_out);

/// What run.json records under "invocation" for every simulation command:
/// config_file (null for the built-in case), overrides, out and the memory
/// estimate `memory` (memory_json).  The impact adds its restart.
[[nodiscard]] nlohmann::json invocation_json(const CaseOptions& options,
                                             const nlohmann::json& memory);

/// Refuses an empty argument that names a file or directory ("must name a
/// config file, not be empty").
[[nodiscard]] CLI::Validator not_empty(const std::string& what);

/// Refuses an argument of an option that names a file or directory when it is
/// empty ("--out: must name a directory, not be empty"), starts with '-', as
/// an option that stood in its place does, or starts with '=' ("--out==x").
[[nodiscard]] CLI::Validator path_name(const std::string& what);

/// Refuses an integer option's value unless it is written in decimal digits,
/// and passes it on without its leading zeros (CLI11 reads 011 as octal).
[[nodiscard]] CLI::Validator decimal_integer();

/// -q/--quiet: print nothing but errors.
void add_quiet_flag(CLI::App& command, bool& quiet);

/// The error of an argument that CLI11 would misread, else "": a value given
/// to a flag ("--quiet=5", which it read as --quiet: "--quiet takes no
/// value"), a short option with '=' ("-o=run" and "-qo=run", which it read
/// as the directory "=run"), or a long one with an empty value ("--out= r",
/// which took "r").  Options are those of the command argv[1] names, or of
/// ehlsim itself; arguments after "--" are positional.
[[nodiscard]] std::string refused_option_form(const CLI::App& app, int argc, char** argv);

/// The commands, for the messages of a command line that names none.
inline constexpr std::string_view kCommandList =
    "commands: impact, spike, study, rolling; try ehlsim --help";

/// `text` with what a terminal would act on as escapes ("\x0a"): the control
/// characters (a path with a newline in it kept a one-line message from being
/// one line), UTF-8's C1 controls, bidirectional controls, separators and
/// invisible format characters, and bytes that form no UTF-8 character.
/// Other UTF-8 text stays as it is.
[[nodiscard]] std::string printable(std::string_view text);

/// The one line for a command-line error of CLI11 that says what is allowed:
/// "Could not convert: --grid = abc" names the type the option takes, "At
/// Most 1 required but received 2" that the option is given once, and "A
/// subcommand is required" the option that stood in its place (`argv`).
[[nodiscard]] std::string parse_error_text(const CLI::ParseError& error, const CLI::App& app,
                                           int argc, char** argv);

}  // namespace cli
