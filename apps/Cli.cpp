#include "Cli.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cstdio>
#include <limits>
#include <new>
#include <string>
#include <utility>
#include <vector>

#include "config/Parameters.hpp"

namespace cli {

namespace {
/// A runaway word of a message (ehlsim::echo_input) with the quotes and
/// punctuation around it kept: `'/a/b...',` stays quoted and followed by
/// its comma, and the size is the word's own.
std::string shortened_word(std::string_view word) {
  constexpr std::string_view kOpening = "'\"(", kClosing = "'\"),:;.";
  const std::size_t first = word.find_first_not_of(kOpening);
  const std::size_t last = word.find_last_not_of(kClosing);
  if (first == std::string_view::npos || last == std::string_view::npos || last < first)
    return ehlsim::echo_input(word);
  return std::string(word.substr(0, first)) +
         ehlsim::echo_input(word.substr(first, last + 1 - first)) +
         std::string(word.substr(last + 1));
}
}  // namespace

void write_out(std::string_view text) {
  std::fwrite(text.data(), 1, text.size(), stdout);  // its error is the reader's
}

void print_error(std::string_view message) {
  // After what stdout holds so far, also when both go to one file (a study's
  // case log, whose last line the study reports as the reason).
  std::fflush(stdout);
  // Longer than PATH_MAX: no file name, a value nobody wants to read in full.
  constexpr std::size_t kLongestWord = 4096;
  std::string line;
  std::size_t start = 0;
  while (start <= message.size()) {
    const std::size_t end = std::min(message.find(' ', start), message.size());
    const std::string_view word = message.substr(start, end - start);
    line += word.size() > kLongestWord ? shortened_word(word) : std::string(word);
    if (end < message.size()) line += ' ';
    start = end + 1;
  }
  // Control characters as escapes: an ESC of an argument reached the terminal,
  // and a newline in a path read as a space named another file ('cfg .toml').
  std::fprintf(stderr, "ehlsim: error: %s\n", printable(line).c_str());
}

std::string failure_reason(const std::exception& e) {
  if (dynamic_cast<const std::bad_alloc*>(&e) == nullptr) return e.what();
  // The memory guard knows the machine's available memory and
  // solver.memory_limit_mb, not a limit of the process (io/MemoryGuard.hpp).
  return "out of memory (std::bad_alloc): this process may not allocate more, by a limit of its "
         "own (ulimit -v, a memory cgroup) or the machine's; use fewer grid.points, or raise the "
         "limit";
}

void print_warnings(const std::vector<std::string>& warnings) {
  std::fflush(stdout);
  for (const std::string& warning : warnings)
    std::fprintf(stderr, "ehlsim: warning: %s\n", warning.c_str());
}

namespace {
/// A validator's message starts with this and the value: CLI11 puts "--out: "
/// before it, and parse_error_text makes that "--out = VALUE: ...", as the
/// other errors name a key and its value.
constexpr std::string_view kValueMark = "= ";

/// What an option of CLI11's type name `type` takes, for messages.
std::string value_text(const std::string& type) {
  if (type == "INT")
    return fmt::format("a whole number of at most {} in decimal digits",
                       std::numeric_limits<int>::max());
  if (type == "UINT") return "a whole number";
  if (type == "FLOAT") return "a number";
  return "a value of type " + type;
}
}  // namespace

CLI::Validator not_empty(const std::string& what) {
  return CLI::Validator(
      [what](const std::string& value) {
        return value.empty() ? "must name " + what + ", not be empty" : std::string();
      },
      "", "NOT_EMPTY");
}

CLI::Validator path_name(const std::string& what) {
  return CLI::Validator(
      [what](const std::string& value) {
        if (std::string empty = not_empty(what)(value); !empty.empty()) return empty;
        // `impact --out --set case.M=5` took "--set" as the directory ("-"
        // reads as standard input or output).
        if (value.front() == '-')
          return fmt::format(
              "{0}{1}: looks like an option, not {2}: write ./{1} for a name "
              "that starts with '-'",
              kValueMark, printable(value), what);
        // `--out==x` made the directory "=x".
        if (value.front() == '=')
          return fmt::format(
              "{0}{1}: starts with '=' (one '=' too many?): write ./{1} for a name "
              "that starts with '='",
              kValueMark, printable(value));
        return std::string();
      },
      "", "PATH_NAME");
}

CLI::Validator decimal_integer() {
  return CLI::Validator(
      [](std::string& value) {
        // CLI11 also reads 0x21, 0o41 and 0b100001 as integers, and 011 as octal 9.
        const std::size_t sign = value.starts_with('+') ? 1 : 0;
        const bool digits =
            value.size() > sign && value.find_first_not_of("0123456789", sign) == std::string::npos;
        if (!digits)
          return fmt::format("{}{}: must be {} (see --help)", kValueMark, printable(value),
                             value_text("INT"));
        const std::size_t first = std::min(value.find_first_not_of('0', sign), value.size() - 1);
        value.erase(0, first);  // "+0033" is 33
        return std::string();
      },
      "", "DECIMAL");
}

void add_quiet_flag(CLI::App& command, bool& quiet) {
  command.add_flag("-q,--quiet", quiet, "print nothing but errors");
}

namespace {
/// The command that argv[1] names, or nullptr.
const CLI::App* command_given(const CLI::App& app, int argc, char** argv) {
  const std::string_view first = argc > 1 ? argv[1] : "";
  const std::vector<const CLI::App*> named =
      app.get_subcommands([&](const CLI::App* c) { return c->get_name() == first; });
  return named.empty() ? nullptr : named.front();
}

/// The option's name in an argument: "--out" of "--out=x", "-q" of "-qo".
std::string option_name(std::string_view arg) {
  return std::string(arg.substr(0, arg.starts_with("--") ? arg.find('=') : 2));
}

/// The option `name` of the command that argv[1] names, or of ehlsim itself
/// when argv[1] names none (`ehlsim --help=1`); nullptr where it has none:
/// CLI11 then says what it does not expect.
const CLI::Option* option_of_command(const CLI::App& app, const std::string& name, int argc,
                                     char** argv) {
  if (const CLI::App* command = command_given(app, argc, argv))
    return command->get_option_no_throw(name);
  return app.get_option_no_throw(name);
}

/// The letters of a short cluster "-abc" as CLI11 reads them: `option`, the
/// one it gives the text after it: its first letter that takes a value
/// ("-oq=x" is -o with "q=x", as "-ofile" is -o with "file"), else its last
/// (a flag, or nullptr: unknown); `stray`, whether a character that names no
/// option comes before that, after flags only: CLI11 made an argument of the
/// rest, and read -q-out=x as -q --out=x, -q- as -q, and '-q ' as -q with the
/// config file '- '.
struct Cluster {
  const CLI::Option* option = nullptr;
  bool stray = false;
};

Cluster read_cluster(const CLI::App& app, std::string_view letters, int argc, char** argv) {
  Cluster cluster;
  for (const char letter : letters) {
    if (std::isalnum(static_cast<unsigned char>(letter)) == 0) return {nullptr, true};
    cluster.option = option_of_command(app, std::string("-") + letter, argc, argv);
    if (cluster.option == nullptr || cluster.option->get_expected_max() != 0) return cluster;
  }
  return cluster;
}

/// The command named after `first` that has the option `first` names:
/// "ehlsim --quiet impact" was told only that --quiet was not expected.
std::string command_after(const CLI::App& app, std::string_view first, int argc, char** argv) {
  const std::string name = option_name(first);
  if (app.get_option_no_throw(name) != nullptr) return {};  // ehlsim's own: --help, --version
  for (int i = 2; i < argc && std::string_view(argv[i]) != "--"; ++i) {
    for (const CLI::App* command : app.get_subcommands({})) {
      if (!command->check_name(argv[i])) continue;
      const CLI::Option* option = command->get_option_no_throw(name);
      if (option == nullptr) return {};
      // "-o impact rolling": impact is the value of -o, rolling the command.
      const bool value_next = option->get_expected_max() != 0 && first.find('=') == first.npos &&
                              first.size() == name.size();
      if (!(value_next && i == 2)) return command->get_name();
    }
  }
  return {};
}

/// "--version" after the command: an option of ehlsim itself, which CLI11
/// said only it did not expect.
std::string ehlsim_option_after_command(const CLI::App& app, std::string_view arg, int argc,
                                        char** argv) {
  const CLI::App* command = command_given(app, argc, argv);
  if (!arg.starts_with("--") || command == nullptr) return {};
  const std::string name = option_name(arg);
  if (command->get_option_no_throw(name) != nullptr || app.get_option_no_throw(name) == nullptr)
    return {};
  return fmt::format("{}: an option of ehlsim itself, not of {}: ehlsim {}", printable(arg),
                     command->get_name(), name);
}
}  // namespace

std::string refused_option_form(const CLI::App& app, int argc, char** argv) {
  if (argc > 2 && std::string_view(argv[1]).starts_with('-')) {
    if (const std::string command = command_after(app, argv[1], argc, argv); !command.empty())
      return fmt::format("{}: options follow the command: ehlsim {} {} ...", printable(argv[1]),
                         command, printable(argv[1]));
    // "ehlsim --bogus --version" printed the version, exit 0.
    const std::string_view first = argv[1];
    if (first != "--" && app.get_option_no_throw(option_name(first)) == nullptr)
      return fmt::format("'{}' is neither a command nor an option of ehlsim ({})",
                         ehlsim::echo_input(first), kCommandList);
  }
  for (int i = 1; i < argc; ++i) {
    const std::string_view arg = argv[i];
    if (arg == "--") break;  // positional arguments from here on
    if (std::string misplaced = ehlsim_option_after_command(app, arg, argc, argv);
        !misplaced.empty())
      return misplaced;
    if (arg.size() > 2 && arg[0] == '-' && arg[1] != '-' &&
        read_cluster(app, arg.substr(1, arg.find('=') - 1), argc, argv).stray)
      return fmt::format(
          "{}: a group of short options holds a character that names none: give each option on "
          "its own (see --help)",
          printable(arg));
    const std::size_t equals = arg.find('=');
    if (!arg.starts_with('-') || equals == std::string_view::npos || equals < 2) continue;
    const std::string name(arg.substr(0, equals));
    const bool is_long = name.starts_with("--");
    const CLI::Option* option = is_long ? option_of_command(app, name, argc, argv)
                                        : read_cluster(app, name.substr(1), argc, argv).option;
    if (option == nullptr) continue;
    // --quiet=5 and --quiet=no were read as --quiet, --no-plots=0 as --no-plots.
    if (option->get_expected_max() == 0)
      return fmt::format("{}: {} takes no value (see --help)", printable(arg),
                         is_long ? name : "-" + option->get_snames().front());
    // The value-taking letter of a cluster is found by its short name.
    const std::string letter = is_long ? std::string() : "-" + option->get_snames().front();
    if (!is_long && name.ends_with(letter.substr(1))) {
      // CLI11 reads -o=run (and -qo=run) as the directory "=run".
      const std::vector<std::string>& long_names = option->get_lnames();
      return fmt::format("{}: a short option takes its value after a space: {} VALUE{}",
                         printable(arg), letter,
                         long_names.empty() ? "" : " or --" + long_names.front() + "=VALUE");
    }
    // "--out= run" took "run" as the value.
    if (is_long && equals + 1 == arg.size()) return name + " is given no value (see --help)";
  }
  return {};
}

namespace {
/// CLI11's "The following arguments were not expected: b3 --out --" (its
/// list backwards, with the "--" separator) as "'--out', 'b3': not expected
/// by ehlsim impact: ...", or empty when `what` is no such text.
std::string unexpected_arguments_text(const std::string& what, const CLI::App& app, int argc,
                                      char** argv) {
  std::string list;
  for (const std::string_view intro :
       {"The following argument was not expected: ", "The following arguments were not expected: "})
    if (what.starts_with(intro)) list = what.substr(intro.size());
  if (list.empty()) return {};
  std::vector<std::string> words;
  for (std::size_t start = 0; start <= list.size();) {
    const std::size_t end = std::min(list.find(' ', start), list.size());
    if (const std::string word = list.substr(start, end - start); !word.empty() && word != "--")
      words.insert(words.begin(), "'" + word + "'");
    start = end + 1;
  }
  const CLI::App* command = command_given(app, argc, argv);
  const std::string who =
      command != nullptr ? fmt::format("ehlsim {}", command->get_name()) : std::string("ehlsim");
  return fmt::format(
      "{}: not expected by {}: an option it does not have, or one argument too "
      "many (see {} --help)",
      fmt::join(words, ", "), who, who);
}
}  // namespace

std::string parse_error_text(const CLI::ParseError& error, const CLI::App& app, int argc,
                             char** argv) {
  std::string what = error.what();
  if (const std::size_t mark = what.find(fmt::format(": {}", kValueMark));
      what.starts_with('-') && mark != std::string::npos)
    what.erase(mark, 1);  // a validator's "--grid: = 0x21: ..."
  constexpr std::string_view kNotConverted = "Could not convert: ";
  constexpr std::string_view kOnce = ": At Most 1 required but received ";
  constexpr std::string_view kMissing = ": 1 required ";  // "--out: 1 required TEXT missing"
  if (what.starts_with(kNotConverted)) {
    const std::string given = what.substr(kNotConverted.size());  // "--grid = abc"
    const std::string name = given.substr(0, given.find(" = "));
    if (const CLI::Option* option = option_of_command(app, name, argc, argv))
      return fmt::format("{}: must be {} (see --help)", given, value_text(option->get_type_name()));
  } else if (const std::size_t at = what.find(kOnce); at != std::string::npos) {
    return fmt::format("{} is given {} times: give it once", what.substr(0, at),
                       what.substr(at + kOnce.size()));
  } else if (const std::size_t gap = what.find(kMissing);
             what.starts_with('-') && gap != std::string::npos && what.ends_with(" missing")) {
    return fmt::format("{} is given no value (see --help)", what.substr(0, gap));
  } else if (std::string unexpected = unexpected_arguments_text(what, app, argc, argv);
             !unexpected.empty()) {
    return unexpected;
  } else if (what == "A subcommand is required") {
    return argc > 1 ? fmt::format("'{}' is neither a command nor an option of ehlsim ({})",
                                  ehlsim::echo_input(argv[1]), kCommandList)
                    : fmt::format("no command given ({})", kCommandList);
  }
  return what;
}

namespace {
/// The length of the well-formed UTF-8 sequence at the start of `text`, and
/// its code point; {1, -1} for a byte that starts none.
std::pair<std::size_t, long> utf8_sequence(std::string_view text) {
  const auto byte = [&](std::size_t i) { return static_cast<unsigned char>(text[i]); };
  const unsigned char lead = byte(0);
  const std::size_t length = lead >= 0xf0 ? 4 : lead >= 0xe0 ? 3 : lead >= 0xc2 ? 2 : 0;
  if (length == 0 || lead > 0xf4 || text.size() < length) return {1, -1};
  long code = lead & (0x7f >> length);
  for (std::size_t i = 1; i < length; ++i) {
    if ((byte(i) & 0xc0) != 0x80) return {1, -1};
    code = (code << 6) | (byte(i) & 0x3f);
  }
  // The smallest code point of each length: below it the sequence is overlong.
  constexpr std::array<long, 5> kSmallest = {0, 0, 0x80, 0x800, 0x10000};
  const bool overlong = code < kSmallest[length];
  if (overlong || code > 0x10ffff || (code >= 0xd800 && code <= 0xdfff)) return {1, -1};
  return {length, code};
}

/// Code points a terminal acts on, or shows as nothing, rather than as a
/// character: the C1 controls (U+009B is a CSI), the bidirectional marks,
/// overrides and isolates, which reorder what follows them on the line, the
/// line and paragraph separators, and the invisible format characters (zero
/// widths, soft hyphen, tags), which make two names look alike.
bool acts_on_terminal(long code) {
  return (code >= 0x80 && code <= 0x9f) || code == 0xad || code == 0x061c || code == 0x180e ||
         (code >= 0x200b && code <= 0x200f) || (code >= 0x2028 && code <= 0x202e) ||
         (code >= 0x2060 && code <= 0x206f) || code == 0xfeff ||
         (code >= 0xfff9 && code <= 0xfffb) || (code >= 0xe0000 && code <= 0xe007f);
}
}  // namespace

std::string printable(std::string_view text) {
  std::string out;
  const auto escape = [&](std::string_view bytes) {
    for (const char c : bytes) out += fmt::format("\\x{:02x}", static_cast<unsigned char>(c));
  };
  for (std::size_t i = 0; i < text.size();) {
    const unsigned char c = static_cast<unsigned char>(text[i]);
    if (c < 0x80) {
      if (std::iscntrl(c) != 0)
        escape(text.substr(i, 1));
      else
        out += static_cast<char>(c);
      ++i;
      continue;
    }
    // Other UTF-8 text as it is (a path in any language); bytes that form no
    // character, which a terminal in an 8-bit charset may take for C1, as escapes.
    const auto [length, code] = utf8_sequence(text.substr(i));
    if (code < 0 || acts_on_terminal(code))
      escape(text.substr(i, length));
    else
      out += text.substr(i, length);
    i += length;
  }
  return out;
}

nlohmann::json invocation_json(const CaseOptions& options, const nlohmann::json& memory) {
  return {{"config_file", options.config_file.empty() ? nlohmann::json(nullptr)
                                                      : nlohmann::json(options.config_file)},
          {"overrides", options.overrides},
          {"out", options.out_dir},
          {"memory", memory}};
}

void add_case_options(CLI::App& command, CaseOptions& options, const std::string& default_case,
                      const std::string& what_out) {
  // An empty CONFIG ("-- ''") ran the built-in case.
  command
      .add_option("config", options.config_file,
                  "TOML file with the case (default: " + default_case + ")")
      ->check(not_empty("a config file"));
  command
      .add_option("-o,--out", options.out_dir,
                  "run directory for " + what_out + " (created if missing)")
      ->check(path_name("a directory"))
      ->capture_default_str();
  command
      .add_option("--set", options.overrides,
                  "override one parameter, e.g. --set case.M=20 (repeatable, applied in order)")
      ->type_name("KEY=VALUE")
      ->allow_extra_args(false)
      ->take_all();
}

}  // namespace cli
