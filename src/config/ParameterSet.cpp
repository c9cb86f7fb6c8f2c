// Declaring keys, reading a TOML file and --set overrides, validating them
// against a ParameterSet, and its --help text: the machinery of every mode.
#include "config/ParameterSet.hpp"

#include <fmt/format.h>
#include <toml++/toml.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <sstream>
#include <string_view>
#include <system_error>
#include <utility>
#include <vector>

#include "config/SystemFailure.hpp"

namespace ehlsim {

namespace {
/// `message` with each NUL byte written as the escape "\x00": what() is a C
/// string, which would end at a NUL that a TOML value or key may hold ("\u0000"),
/// and the line would lose the rest of its words.  cli::printable writes the
/// other control characters in the same form.
std::string with_nul_escaped(const std::string& message) {
  std::string out;
  out.reserve(message.size());
  for (const char c : message) {
    if (c == '\0')
      out += "\\x00";
    else
      out += c;
  }
  return out;
}
}  // namespace

ConfigError::ConfigError(const std::string& message, std::string key)
    : std::runtime_error(with_nul_escaped(message)), key_(std::move(key)) {}

std::string echo_input(std::string_view text) {
  if (text.size() <= kEchoMaxChars) return std::string(text);
  std::size_t cut = kEchoMaxChars;
  // Not inside a UTF-8 sequence: continuation bytes are 10xxxxxx.
  constexpr unsigned char kContinuationMask = 0xC0, kContinuation = 0x80;
  while (cut > 0 && (static_cast<unsigned char>(text[cut]) & kContinuationMask) == kContinuation)
    --cut;
  return fmt::format("{}... ({} bytes)", text.substr(0, cut), text.size());
}

std::string double_underflow_reason() {
  return fmt::format(
      "is too small for a double, which would read it as 0 (the smallest positive double is {:g})",
      std::numeric_limits<double>::denorm_min());
}

bool underflowed_to_zero(double value, std::string_view literal) {
  const std::string_view mantissa = literal.substr(0, literal.find_first_of("eE"));
  return value == 0.0 && mantissa.find_first_of("123456789") != std::string_view::npos;
}

std::string double_overflow_reason() {
  return fmt::format("is beyond the range of a double (magnitudes up to {:g})",
                     std::numeric_limits<double>::max());
}

namespace {
/// The largest config file read: a case is a few hundred bytes, a long
/// output.snapshot_times list some kB; a runaway value of 10 MB is still read
/// (to be refused with its key named, shortened).
constexpr std::size_t kMaxConfigBytes = std::size_t{16} << 20;
/// The most levels a config file may nest: each dot of a key outside quotes
/// is a level of tables, each bracket or brace one more, and toml++ 3.3
/// parses and frees them recursively: a key of 50 000 parts (100 kB), or 150
/// inline tables each under a key of 250 parts, overflowed the stack
/// (SIGSEGV).  ehlsim's keys have one dot (section.key).
constexpr int kMaxNestingLevels = 256;
}  // namespace

// ---------------------------------------------------------------------------
// The registry
// ---------------------------------------------------------------------------

Bound above(double v) { return {v, false}; }
Bound at_least(double v) { return {v, true}; }
Bound at_most(double v) { return {v, true}; }
Bound below(double v) { return {v, false}; }

ParameterSpec real(std::string key, std::optional<double> def, std::string default_text,
                   std::optional<Bound> lower, std::optional<Bound> upper, std::string units,
                   std::string doc) {
  ParameterSpec s;
  s.key = std::move(key);
  s.type = ParameterType::Float;
  if (def) s.default_value = *def;
  s.default_text = std::move(default_text);
  s.lower = lower;
  s.upper = upper;
  s.units = std::move(units);
  s.doc = std::move(doc);
  return s;
}

ParameterSpec integer(std::string key, int def, std::optional<Bound> lower,
                      std::optional<Bound> upper, bool power_of_two_plus_one, std::string doc) {
  ParameterSpec s;
  s.key = std::move(key);
  s.type = ParameterType::Int;
  s.default_value = def;
  s.lower = lower;
  // An int holds the value: the help and the errors say so (3e9 was refused
  // as "too large" where the help said ">= 1").
  s.upper = upper ? upper : at_most(std::numeric_limits<int>::max());
  s.power_of_two_plus_one = power_of_two_plus_one;
  s.doc = std::move(doc);
  return s;
}

ParameterSpec boolean(std::string key, bool def, std::string doc) {
  ParameterSpec s;
  s.key = std::move(key);
  s.type = ParameterType::Bool;
  s.default_value = def;
  s.doc = std::move(doc);
  return s;
}

ParameterSpec choice(std::string key, std::string_view def, std::vector<std::string> choices,
                     std::string doc) {
  ParameterSpec s;
  s.key = std::move(key);
  s.type = ParameterType::Enum;
  s.default_value = std::string(def);
  s.choices = std::move(choices);
  s.doc = std::move(doc);
  return s;
}

ParameterSpec real_array(std::string key, std::optional<Bound> lower, std::string doc) {
  ParameterSpec s;
  s.key = std::move(key);
  s.type = ParameterType::FloatArray;
  s.default_value = std::vector<double>{};
  s.lower = lower;
  s.doc = std::move(doc);
  return s;
}

namespace {

std::string format_number(double v) { return fmt::format("{:g}", v); }

std::string quoted_list(const std::vector<std::string>& items) {
  std::string out;
  for (const auto& item : items) {
    if (!out.empty()) out += ", ";
    out += '"' + item + '"';
  }
  return out;
}

/// "> 0", ">= 0", "< 1", "in [0, 0.5]", "" for a plain interval; `whole_numbers`
/// writes the bounds out in full (2147483647, not 2.14748e+09).
std::string interval_text(const std::optional<Bound>& lower, const std::optional<Bound>& upper,
                          bool whole_numbers = false) {
  const auto number = [&](double v) {
    return whole_numbers ? fmt::format("{:.0f}", v) : format_number(v);
  };
  if (lower && upper) {
    return fmt::format("in {}{}, {}{}", lower->inclusive ? "[" : "(", number(lower->value),
                       number(upper->value), upper->inclusive ? "]" : ")");
  }
  if (lower) return fmt::format("{} {}", lower->inclusive ? ">=" : ">", number(lower->value));
  if (upper) return fmt::format("{} {}", upper->inclusive ? "<=" : "<", number(upper->value));
  return {};
}

bool in_interval(const std::optional<Bound>& lower, const std::optional<Bound>& upper, double v) {
  if (std::isnan(v)) return false;
  if (lower && !(lower->inclusive ? v >= lower->value : v > lower->value)) return false;
  if (upper && !(upper->inclusive ? v <= upper->value : v < upper->value)) return false;
  return true;
}

}  // namespace

std::string_view ParameterSpec::section() const {
  const std::string_view k = key;
  return k.substr(0, k.find('.'));
}

std::string_view ParameterSpec::name() const {
  const std::string_view k = key;
  return k.substr(k.find('.') + 1);
}

std::string ParameterSpec::allowed() const {
  switch (type) {
    case ParameterType::Bool:
      return "true or false";
    case ParameterType::Enum:
      return "one of " + quoted_list(choices);
    case ParameterType::FloatArray: {
      const std::string range = interval_text(lower, upper);
      return range.empty() ? "an array of numbers" : "an array of numbers " + range;
    }
    case ParameterType::Int: {
      if (power_of_two_plus_one && lower && upper) {
        return fmt::format("2^k + 1 between {} and {}", format_number(lower->value),
                           format_number(upper->value));
      }
      // Whole numbers written out (2147483647, not 2.14748e+09).
      const std::string range = interval_text(lower, upper, /*whole_numbers=*/true);
      return range.empty() ? "an integer" : range;
    }
    case ParameterType::Float: {
      const std::string range = interval_text(lower, upper);
      return range.empty() ? "a finite number" : range;
    }
  }
  return {};
}

std::string ParameterSpec::default_description() const {
  if (!default_value) return default_text.empty() ? "none" : default_text;
  return std::visit(
      [](const auto& v) -> std::string {
        using T = std::decay_t<decltype(v)>;
        if constexpr (std::is_same_v<T, bool>) {
          return v ? "true" : "false";
        } else if constexpr (std::is_same_v<T, int>) {
          return std::to_string(v);
        } else if constexpr (std::is_same_v<T, double>) {
          return format_number(v);
        } else if constexpr (std::is_same_v<T, std::string>) {
          return '"' + v + '"';
        } else {
          std::string out = "[";
          for (std::size_t i = 0; i < v.size(); ++i) out += (i ? ", " : "") + format_number(v[i]);
          return out + "]";
        }
      },
      *default_value);
}

const ParameterSpec* ParameterSet::find(std::string_view key) const {
  const auto it = std::find_if(specs.begin(), specs.end(),
                               [&](const ParameterSpec& s) { return s.key == key; });
  return it == specs.end() ? nullptr : &*it;
}

// ---------------------------------------------------------------------------
// Reading: TOML tree -> validated values
// ---------------------------------------------------------------------------

namespace {

bool is_known_section(const ParameterSet& set, std::string_view name) {
  const auto& sections = set.sections;
  return std::any_of(sections.begin(), sections.end(),
                     [&](const SectionSpec& s) { return s.name == name; });
}

std::string section_list(const ParameterSet& set) {
  std::string out;
  for (const auto& s : set.sections) out += (out.empty() ? "" : ", ") + s.name;
  return out;
}

std::string keys_in_section(const ParameterSet& set, std::string_view section) {
  std::string out;
  for (const auto& s : set.specs) {
    if (s.section() == section) out += (out.empty() ? "" : ", ") + std::string(s.name());
  }
  return out;
}

/// A value as the user wrote it, for messages (TOML-like syntax).
std::string node_text(const toml::node& node) {
  if (node.is_table()) return "{...}";
  if (const auto* v = node.as_boolean()) return v->get() ? "true" : "false";
  if (const auto* v = node.as_integer()) return std::to_string(v->get());
  if (const auto* v = node.as_floating_point()) return fmt::format("{}", v->get());
  if (const auto* v = node.as_string()) return '"' + v->get() + '"';
  if (const auto* a = node.as_array()) {
    std::string out = "[";
    for (std::size_t i = 0; i < a->size(); ++i) out += (i ? ", " : "") + node_text(*a->get(i));
    return out + "]";
  }
  std::ostringstream os;
  node.visit([&](const auto& v) {
    if constexpr (!toml::is_table<decltype(v)>) os << v;
  });
  return os.str();
}

/// Where a value came from: "file.toml:LINE:COL" for a node of the config
/// file `file` ("" when there is none), else the origin its override was
/// parsed with ("--set", or a file the overrides were taken from).
std::string node_origin(const toml::node& node, std::string_view file) {
  const toml::source_region& src = node.source();
  if (!src.path) return std::string(kOverrideOrigin);
  if (!file.empty() && *src.path == file) {
    return fmt::format("{}:{}:{}", *src.path, src.begin.line, src.begin.column);
  }
  return *src.path;
}

std::string origin_suffix(const std::string& origin) {
  return origin.empty() ? std::string() : " (" + origin + ")";
}

/// "v = VALUE" with VALUE a TOML string of `value`, parsed with `origin` as
/// its source (a string made without one named "--set" as its origin, also
/// for a value of a run.json), or nothing when `value` is no UTF-8.
std::optional<toml::table> as_string_value(const std::string& value, std::string_view origin) {
  std::string quoted = "v = \"";
  constexpr unsigned char kFirstPrintable = 0x20, kDelete = 0x7f;
  for (const char c : value) {
    const auto byte = static_cast<unsigned char>(c);
    if (c == '"' || c == '\\') quoted += '\\';
    if (byte < kFirstPrintable || byte == kDelete)
      quoted += fmt::format("\\u{:04x}", byte);
    else
      quoted += c;
  }
  try {
    return toml::parse(quoted + '"', origin);
  } catch (const toml::parse_error&) {
    return std::nullopt;
  }
}

[[noreturn]] void fail_value(const std::string& key, const std::string& text,
                             const std::string& problem, const std::string& origin) {
  throw ConfigError(fmt::format("{} = {}: {}{}", echo_input(key), echo_input(text), problem,
                                origin_suffix(origin)),
                    key);
}

std::optional<double> number_of(const toml::node& node) {
  if (const auto* v = node.as_integer()) return static_cast<double>(v->get());
  if (const auto* v = node.as_floating_point()) return v->get();
  return std::nullopt;
}

std::string with_space(const std::string& s) { return s.empty() ? s : " " + s; }

/// Throws the one-line error of a given value: key, value as written, what is
/// allowed, and where it was given.
struct ValueProblem {
  const ParameterSpec& spec;
  const Given& given;
  [[noreturn]] void operator()(const std::string& problem) const {
    fail_value(spec.key, given.text, problem, given.origin);
  }
};

ParameterValue convert_enum(const ParameterSpec& spec, const toml::node& node,
                            const ValueProblem& fail) {
  const auto* v = node.as_string();
  if (!v || std::find(spec.choices.begin(), spec.choices.end(), v->get()) == spec.choices.end()) {
    fail("must be " + spec.allowed());
  }
  return v->get();
}

ParameterValue convert_float(const ParameterSpec& spec, const toml::node& node,
                             const ValueProblem& fail) {
  const std::string range = interval_text(spec.lower, spec.upper);
  const std::optional<double> v = number_of(node);
  if (!v || std::isnan(*v)) fail("must be a number" + with_space(range));
  // As the help writes it: "> 0 or inf" where inf is allowed.
  const std::string allowed = spec.allow_infinite ? range + " or inf" : range;
  if (std::isinf(*v) && !(spec.allow_infinite && *v > 0)) {
    fail(spec.allow_infinite ? "must be " + allowed
                             : "must be a finite number" + with_space(range));
  }
  if (!in_interval(spec.lower, spec.upper, *v)) fail("must be " + allowed);
  return *v;
}

ParameterValue convert_int(const ParameterSpec& spec, const toml::node& node,
                           const ValueProblem& fail) {
  std::optional<double> v;
  if (const auto* i = node.as_integer()) {
    v = static_cast<double>(i->get());
  } else if (const auto* f = node.as_floating_point();
             f && std::isfinite(f->get()) && std::trunc(f->get()) == f->get()) {
    v = f->get();  // an integral float such as 257.0
  }
  if (!v) {
    const std::string allowed = spec.allowed();
    fail(allowed == "an integer" ? "must be an integer" : "must be an integer " + allowed);
  }
  const bool fits = *v >= static_cast<double>(std::numeric_limits<int>::min()) &&
                    *v <= static_cast<double>(std::numeric_limits<int>::max());
  if (!fits) fail("must be " + spec.allowed());
  const bool ok = in_interval(spec.lower, spec.upper, *v) &&
                  (!spec.power_of_two_plus_one || is_power_of_two_plus_one(static_cast<long>(*v)));
  if (!ok) fail("must be " + spec.allowed());
  return static_cast<int>(*v);
}

ParameterValue convert_float_array(const ParameterSpec& spec, const toml::node& node,
                                   const ValueProblem& fail) {
  std::vector<double> values;
  if (const std::optional<double> single = number_of(node)) {
    values.push_back(*single);  // a single number is a one-entry array
  } else if (const auto* a = node.as_array()) {
    for (const auto& element : *a) {
      const std::optional<double> v = number_of(element);
      if (!v) fail("must be " + spec.allowed());
      values.push_back(*v);
    }
  } else {
    fail("must be " + spec.allowed());
  }
  const std::string range = interval_text(spec.lower, spec.upper);
  for (const double v : values) {
    if (!std::isfinite(v)) fail("every entry must be a finite number" + with_space(range));
    if (!in_interval(spec.lower, spec.upper, v)) fail("every entry must be " + range);
  }
  return values;
}

Given convert(const ParameterSpec& spec, const toml::node& node, std::string_view file) {
  Given g;
  g.text = node_text(node);
  g.origin = node_origin(node, file);
  const ValueProblem fail{spec, g};
  switch (spec.type) {
    case ParameterType::Bool: {
      const auto* v = node.as_boolean();
      if (!v) fail("must be true or false");
      g.value = v->get();
      break;
    }
    case ParameterType::Enum:
      g.value = convert_enum(spec, node, fail);
      break;
    case ParameterType::Float:
      g.value = convert_float(spec, node, fail);
      break;
    case ParameterType::Int:
      g.value = convert_int(spec, node, fail);
      break;
    case ParameterType::FloatArray:
      g.value = convert_float_array(spec, node, fail);
      break;
  }
  return g;
}

std::string read_config_text(const std::filesystem::path& path) {
  const auto cannot_read = [&](const std::string& reason) {
    return ConfigError(fmt::format("cannot read config file '{}': {}", path.string(), reason));
  };
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) throw cannot_read("is a directory");
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> file(std::fopen(path.c_str(), "rb"),
                                                       &std::fclose);
  // Out of descriptors or an I/O error is the machine's failure, not the file's (exit 1).
  if (!file) throw_unreadable_input(path, errno, "read config file");
  std::string text;
  constexpr std::size_t kChunk = 1 << 16;
  std::vector<char> buffer(kChunk);
  std::size_t got = 0;
  while ((got = std::fread(buffer.data(), 1, buffer.size(), file.get())) > 0) {
    text.append(buffer.data(), got);
    // /dev/zero, a FIFO that never ends, a wrong file: not read into memory.
    if (text.size() > kMaxConfigBytes)
      throw cannot_read(fmt::format("larger than {} bytes, not a case file", kMaxConfigBytes));
  }
  if (std::ferror(file.get())) throw_unreadable_input(path, errno, "read config file");
  return text;
}

std::string one_line(std::string_view text) {
  std::string out(text);
  std::replace(out.begin(), out.end(), '\n', ' ');
  std::replace(out.begin(), out.end(), '\r', ' ');
  return out;
}

/// Whether the TOML float `node`, written as `literal`, names a nonzero number
/// that was read as 0: "1e-400" gave "case.M = 0: must be > 0".
bool underflowed(const toml::node& node, std::string_view literal) {
  const auto* f = node.as_floating_point();
  return f != nullptr && underflowed_to_zero(f->get(), literal);
}

/// Whether `literal` is a decimal number beyond the range of a double
/// (1e400): TOML refuses to read it, and it was "must be a number".
bool overflows(const std::string& literal) {
  if (literal.empty() || literal.find_first_of("0123456789") == std::string::npos) return false;
  errno = 0;
  char* end = nullptr;
  const double v = std::strtod(literal.c_str(), &end);
  return errno == ERANGE && std::isinf(v) && end == literal.c_str() + literal.size();
}

/// Whether `literal` is a TOML integer beyond 64 bits: decimal
/// (18446744073709551615), or hexadecimal, octal or binary (0x, 0o, 0b; TOML
/// allows no sign there), with or without '_' between digits.  TOML refuses
/// to read it, and it was shown quoted, as if it were text.
bool overflows_integer(std::string literal) {
  std::erase(literal, '_');
  int base = 10;
  std::size_t digits = literal.find_first_not_of("+-") == 1 ? 1 : 0;
  if (literal.size() > 2 && literal[0] == '0' &&
      std::string_view("xob").find(literal[1]) != std::string_view::npos) {
    base = literal[1] == 'x' ? 16 : literal[1] == 'o' ? 8 : 2;
    digits = 2;
  }
  const std::string_view allowed =
      std::string_view("0123456789abcdefABCDEF")
          .substr(0, base == 16 ? std::string_view::npos : static_cast<std::size_t>(base));
  if (literal.size() <= digits || literal.find_first_not_of(allowed, digits) != std::string::npos)
    return false;
  errno = 0;
  if (base == 10) {
    (void)std::strtoll(literal.c_str(), nullptr, 10);
    return errno == ERANGE;
  }
  const unsigned long long v = std::strtoull(literal.c_str() + digits, nullptr, base);
  return errno == ERANGE || v > static_cast<unsigned long long>(INT64_MAX);
}

/// The first integer beyond 64 bits in an override's value: the value
/// itself, or an element of an array.
std::optional<std::string> integer_beyond_64_bits(const std::string& value) {
  constexpr std::string_view kSeparators = "[], \t";
  std::size_t at = 0;
  while (at < value.size()) {
    const std::size_t begin = value.find_first_not_of(kSeparators, at);
    if (begin == std::string::npos) break;
    const std::size_t end = std::min(value.find_first_of(kSeparators, begin), value.size());
    std::string token = value.substr(begin, end - begin);
    if (overflows_integer(token)) return token;
    at = end;
  }
  return std::nullopt;
}

[[noreturn]] void fail_underflow(const std::string& key, std::string_view literal,
                                 const std::string& origin) {
  fail_value(key, std::string(literal), double_underflow_reason(), origin);
}

/// The literal of `node` in the config file whose lines are `lines`.
std::string_view literal_at(const toml::node& node, const std::vector<std::string_view>& lines) {
  const toml::source_position at = node.source().begin;
  if (at.line == 0 || at.line > lines.size()) return {};
  const std::string_view line = lines[at.line - 1];
  const std::size_t begin = std::min<std::size_t>(at.column - 1, line.size());
  const std::size_t end = line.find_first_of(" \t,]}#\r", begin);
  return line.substr(begin, end == std::string_view::npos ? line.size() - begin : end - begin);
}

/// Throws for the first float of `node` (a table, an array or a value, named
/// `key`) that underflowed to 0.
void refuse_underflows(const toml::node& node, const std::string& key,
                       const std::vector<std::string_view>& lines, std::string_view file) {
  if (const auto* table = node.as_table()) {
    for (auto&& [name, child] : *table) {
      const std::string child_key =
          key.empty() ? std::string(name.str()) : key + "." + std::string(name.str());
      refuse_underflows(child, child_key, lines, file);
    }
  } else if (const auto* array = node.as_array()) {
    for (const toml::node& child : *array) refuse_underflows(child, key, lines, file);
  } else if (const std::string_view literal = literal_at(node, lines); underflowed(node, literal)) {
    fail_underflow(key, literal, node_origin(node, file));
  }
}

namespace {
/// The index of the last character of the string that opens at `begin` of
/// `text` (basic or literal, single- or multi-line; text.size() when it does
/// not end, which the parser reports).  `line` counts the newlines in it.
std::size_t end_of_string(std::string_view text, std::size_t begin, std::size_t& line) {
  const char quote = text[begin];
  const bool multi_line = text.substr(begin, 3) == std::string(3, quote);
  for (std::size_t i = begin + (multi_line ? 3 : 1); i < text.size(); ++i) {
    if (text[i] == '\n') {
      if (!multi_line) return i - 1;  // unterminated: the newline is the parser's
      ++line;
    } else if (text[i] == '\\' && quote == '"') {
      // An escape: the next character does not close the string (a newline
      // after a line-ending backslash is still a line).
      if (++i < text.size() && text[i] == '\n') ++line;
    } else if (text[i] == quote && (!multi_line || text.substr(i, 3) == std::string(3, quote))) {
      if (!multi_line) return i;
      // Up to two quotes before the closing three belong to the string
      // ("""q"""" is q"): the run of quotes ends it at its last.
      std::size_t end = i + 2;
      while (end + 1 < text.size() && text[end + 1] == quote && end + 1 < i + 5) ++end;
      return end;
    }
  }
  return text.size();
}

/// The levels of tables and values that a config file nests, as far as
/// refuse_deep_keys follows them: each dot of a key outside quotes and each
/// bracket or brace opens one.
class NestingDepth {
 public:
  /// The depth of the part of a key read so far (one more per dot).
  [[nodiscard]] int key() const { return base() + dots_; }
  void dot() { ++dots_; }
  /// '=': the key ends; a table or array after it nests below it.
  void assign() {
    value_base_ = key() + 1;
    dots_ = 0;
  }
  /// '{' or '[': a level below the key before it, or below the container.
  void open() {
    open_.push_back(std::max(value_base_, base() + dots_ + 1));
    value_base_ = dots_ = 0;
  }
  /// '}' or ']'.
  void close() {
    if (!open_.empty()) open_.pop_back();
    value_base_ = dots_ = 0;
  }
  /// ',' or a newline: the next key starts.
  void separate() { value_base_ = dots_ = 0; }

 private:
  [[nodiscard]] int base() const { return open_.empty() ? 0 : open_.back(); }
  std::vector<int> open_;  ///< the depth inside each open bracket or brace
  int value_base_ = 0;     ///< the depth below the last key, until a separator
  int dots_ = 0;
};

/// Throws ConfigError, naming the line, for a file whose keys, tables and
/// values nest more than kMaxNestingLevels levels (dots of keys outside quotes,
/// brackets and braces): toml++ recurses on each.
void refuse_deep_keys(std::string_view text, const std::filesystem::path& path) {
  NestingDepth depth;
  std::size_t line = 1;
  for (std::size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (c == '"' || c == '\'') {
      i = end_of_string(text, i, line);
    } else if (c == '#') {
      while (i + 1 < text.size() && text[i + 1] != '\n') ++i;
    } else if (c == '.') {
      depth.dot();
    } else if (c == '=') {
      depth.assign();
    } else if (c == '{' || c == '[') {
      depth.open();
    } else if (c == '}' || c == ']') {
      depth.close();
    } else if (c == ',' || c == '\n') {
      depth.separate();
      if (c == '\n') ++line;
    }
    if (depth.key() > kMaxNestingLevels) {
      throw ConfigError(fmt::format(
          "{}:{}: keys, tables and values nested more than {} levels deep (ehlsim's keys are "
          "section.key)",
          path.string(), line, kMaxNestingLevels));
    }
  }
}
}  // namespace

toml::table parse_config_file(const std::filesystem::path& path) {
  const std::string text = read_config_text(path);
  refuse_deep_keys(text, path);
  toml::table root;
  try {
    root = toml::parse(text, std::string_view(path.string()));
  } catch (const toml::parse_error& e) {
    throw ConfigError(fmt::format("{}:{}:{}: {}", path.string(), e.source().begin.line,
                                  e.source().begin.column, one_line(e.description())));
  }
  std::vector<std::string_view> lines;
  for (std::size_t start = 0; start <= text.size();) {
    const std::size_t end = std::min(text.find('\n', start), text.size());
    lines.push_back(std::string_view(text).substr(start, end - start));
    start = end + 1;
  }
  refuse_underflows(root, "", lines, path.string());
  return root;
}

/// The value of an override `key=value` in TOML syntax, or nothing when it is
/// not a single TOML value (then a string); a number that a double or a
/// 64-bit integer cannot hold fails, naming `key`.
std::optional<toml::table> parse_override_value(const std::string& key, const std::string& value,
                                                std::string_view origin) {
  std::optional<toml::table> parsed;
  try {
    parsed = toml::parse("v = " + value, origin);
  } catch (const toml::parse_error&) {
    parsed.reset();
  }
  if (parsed && (parsed->size() != 1 || !parsed->contains("v"))) parsed.reset();
  if (parsed && underflowed(*parsed->get("v"), value))
    fail_underflow(key, value, std::string(origin));
  if (const std::optional<std::string> beyond =
          parsed ? std::nullopt : integer_beyond_64_bits(value)) {
    fail_value(key, value,
               fmt::format("{}is beyond the range of an integer (magnitudes up to {}; a larger "
                           "number is written with an exponent, such as 1e30)",
                           *beyond == value ? "" : *beyond + " ",
                           std::numeric_limits<std::int64_t>::max()),
               std::string(origin));
  }
  if (!parsed && overflows(value)) {
    fail_value(key, value, double_overflow_reason(), std::string(origin));
  }
  return parsed;
}

/// Puts one `section.name=value` override into the tree.
void apply_override(toml::table& root, const std::string& assignment, std::string_view origin,
                    std::string_view file) {
  const std::size_t eq = assignment.find('=');
  const auto trim = [](std::string_view s) {
    constexpr std::string_view kSpace = " \t";
    const std::size_t b = s.find_first_not_of(kSpace);
    if (b == std::string_view::npos) return std::string();
    return std::string(s.substr(b, s.find_last_not_of(kSpace) - b + 1));
  };
  const std::string key =
      eq == std::string::npos ? std::string() : trim(std::string_view(assignment).substr(0, eq));
  if (key.empty()) {
    throw ConfigError(fmt::format("--set '{}': expected KEY=VALUE, e.g. --set case.M=20",
                                  echo_input(assignment)));
  }
  const std::string value = trim(std::string_view(assignment).substr(eq + 1));

  std::optional<toml::table> parsed = parse_override_value(key, value, origin);
  const std::size_t dot = key.find('.');
  toml::table* target = &root;
  std::string name = key;
  if (dot != std::string::npos) {
    const std::string section = key.substr(0, dot);
    name = key.substr(dot + 1);
    toml::node* existing = root.get(section);
    if (!existing) {
      root.insert(section, toml::table{});
      existing = root.get(section);
    }
    target = existing->as_table();
    if (!target) {
      fail_value(section, node_text(*existing),
                 fmt::format("must be a table (section [{}])", section),
                 node_origin(*existing, file));
    }
  }
  if (!parsed) parsed = as_string_value(value, origin);
  if (parsed) {
    parsed->get("v")->visit([&](auto&& node) { target->insert_or_assign(name, std::move(node)); });
  } else {
    target->insert_or_assign(name, value);  // no UTF-8: its origin is "--set"
  }
}

using GivenMap = Inputs::GivenMap;

/// Checks the structure (sections, keys) first, then every value.
GivenMap collect(const toml::table& root, const ParameterSet& set, std::string_view file) {
  for (auto&& [section_key, section_node] : root) {
    const std::string section(section_key.str());
    const auto* table = section_node.as_table();
    if (!is_known_section(set, section)) {
      if (table && !table->empty()) {
        const auto first = table->cbegin();
        const std::string key = section + "." + std::string(first->first.str());
        throw ConfigError(
            fmt::format("unknown key '{}' (unknown section [{}]; known sections: {}){}",
                        echo_input(key), echo_input(section), section_list(set),
                        origin_suffix(node_origin(first->second, file))),
            key);
      }
      if (table) {
        throw ConfigError(
            fmt::format("unknown section '[{}]' (known sections: {}){}", echo_input(section),
                        section_list(set), origin_suffix(node_origin(section_node, file))),
            section);
      }
      throw ConfigError(
          fmt::format(
              "unknown key '{}' (keys belong to a section: {}; write [section] or section.key){}",
              echo_input(section), section_list(set),
              origin_suffix(node_origin(section_node, file))),
          section);
    }
    if (!table) {
      fail_value(section, node_text(section_node),
                 fmt::format("must be a table (section [{}])", section),
                 node_origin(section_node, file));
    }
    // An empty section is no input: an empty [physical] ran the default
    // case, its presence ignored.
    if (table->empty()) {
      throw ConfigError(fmt::format("section [{}] is empty: give its keys (known keys: {}) or "
                                    "leave it out{}",
                                    section, keys_in_section(set, section),
                                    origin_suffix(node_origin(section_node, file))),
                        section);
    }
    for (auto&& [name, node] : *table) {
      const std::string key = section + "." + std::string(name.str());
      if (!set.find(key)) {
        throw ConfigError(
            fmt::format("unknown key '{}' (known keys in [{}]: {}){}", echo_input(key), section,
                        keys_in_section(set, section), origin_suffix(node_origin(node, file))),
            key);
      }
    }
  }
  GivenMap given;
  for (auto&& [section_key, section_node] : root) {
    for (auto&& [name, node] : *section_node.as_table()) {
      const std::string key = std::string(section_key.str()) + "." + std::string(name.str());
      given.emplace(key, convert(*set.find(key), node, file));
    }
  }
  return given;
}

}  // namespace

bool Inputs::any_in_section(std::string_view section) const {
  return std::any_of(given_.begin(), given_.end(), [&](const auto& entry) {
    return std::string_view(entry.first).substr(0, entry.first.find('.')) == section;
  });
}

const ParameterValue& Inputs::default_of(std::string_view key) const {
  const ParameterSpec* spec = set_->find(key);
  if (!spec || !spec->default_value) {
    throw std::logic_error("parameter registry: no default for '" + std::string(key) + "'");
  }
  return *spec->default_value;
}

double Inputs::required_real(const std::string& key, const std::string& why) const {
  if (const Given* g = given(key)) return std::get<double>(g->value);
  throw ConfigError(fmt::format("{} is required {}", key, why), key);
}

void Inputs::fail(const std::string& key, const std::string& problem) const {
  const Given* g = given(key);
  if (!g) {
    // A default the other inputs rule out: name its value as if given.
    const ParameterSpec* spec = set_->find(key);
    if (!spec || !spec->default_value) throw ConfigError(fmt::format("{}: {}", key, problem), key);
    throw ConfigError(
        fmt::format("{} = {} (the default): {}", key, spec->default_description(), problem), key);
  }
  fail_value(key, g->text, problem, g->origin);
}

Inputs read_inputs(const ParameterSet& set, const std::optional<std::filesystem::path>& file,
                   const std::vector<std::string>& overrides, std::string_view origin) {
  toml::table root = file ? parse_config_file(*file) : toml::table{};
  const std::string file_path = file ? file->string() : std::string();
  for (const auto& assignment : overrides) apply_override(root, assignment, origin, file_path);
  return Inputs(collect(root, set, file_path), set);
}

std::string describe_parameters(const ParameterSet& set) {
  std::string out = set.intro;
  const auto type_name = [](const ParameterSpec& s) -> std::string {
    switch (s.type) {
      case ParameterType::Float:
        return "float";
      case ParameterType::Int:
        return "integer";
      case ParameterType::Bool:
        return "bool";
      case ParameterType::Enum:
        return "string";
      case ParameterType::FloatArray:
        return "float array";
    }
    return {};
  };
  for (const auto& section : set.sections) {
    out += fmt::format("\n[{}]  {}\n", section.name, section.doc);
    for (const auto& s : set.specs) {
      if (s.section() != section.name) continue;
      std::string type = type_name(s);
      if (!s.units.empty()) type += " [" + s.units + "]";
      std::string allowed = s.allowed();
      if (s.type == ParameterType::Float && s.allow_infinite) allowed += " or inf";
      out += fmt::format("  {} = {}  ({}, {})\n      {}\n", s.key, s.default_description(), type,
                         allowed, s.doc);
    }
  }
  return out;
}

}  // namespace ehlsim
