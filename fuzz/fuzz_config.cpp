// Fuzzes the configuration reader: a TOML file plus `--set KEY=VALUE`
// overrides into an ImpactConfig (config/Parameters.hpp).  A bad input must end in
// a ConfigError; anything else (a crash, undefined behaviour, another
// exception, a hang) is a finding.
//
// The input: the TOML file, then optionally a line "%%" and one override per
// line.  An input that starts with the "%%" line has no file at all.
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "FuzzFile.hpp"
#include "config/Parameters.hpp"

namespace {

constexpr std::string_view kSeparator = "%%\n";

struct ConfigInput {
  std::optional<std::string> file_text;
  std::vector<std::string> overrides;
};

ConfigInput split(std::string_view bytes) {
  ConfigInput input;
  std::size_t at = std::string_view::npos;
  if (bytes.starts_with(kSeparator)) {
    at = 0;
  } else if (const auto line = bytes.find("\n" + std::string(kSeparator));
             line != std::string_view::npos) {
    at = line + 1;
    input.file_text = std::string(bytes.substr(0, at));
  } else {
    input.file_text = std::string(bytes);
  }
  if (at == std::string_view::npos) return input;
  std::string_view rest = bytes.substr(at + kSeparator.size());
  while (!rest.empty()) {
    const auto end = rest.find('\n');
    input.overrides.emplace_back(rest.substr(0, end));
    rest = end == std::string_view::npos ? std::string_view() : rest.substr(end + 1);
  }
  return input;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static ehlsim::fuzz::FuzzFile file("config.toml");
  const ConfigInput input = split(std::string_view(reinterpret_cast<const char*>(data), size));
  std::optional<std::filesystem::path> path;
  if (input.file_text) {
    path = file.write(reinterpret_cast<const std::uint8_t*>(input.file_text->data()),
                      input.file_text->size());
  }
  try {
    const ehlsim::ImpactConfig config = ehlsim::load_config(path, input.overrides);
    // What a run does next with an accepted config: the echo into run.json.
    const auto echo = ehlsim::effective_parameters_json(config);
    if (echo.dump().empty()) __builtin_trap();
  } catch (const ehlsim::ConfigError&) {
    // The documented answer to a bad input.
  }
  return 0;
}
