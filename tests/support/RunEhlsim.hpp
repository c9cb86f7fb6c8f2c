#pragma once
// Runs the ehlsim binary of this build as a user would (a shell command) and
// captures its exit code, stdout and stderr: for the tests of the command line.
#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <string>

#include "support/TempDir.hpp"
#include "support/TestPaths.hpp"
#include "support/TextFiles.hpp"

namespace ehlsim::testing {

/// `s` quoted for the shell.
inline std::string quote(const std::string& s) {
  std::string out = "'";
  for (const char c : s) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return out + "'";
}

struct Result {
  int exit_code = -1;
  std::string out;
  std::string err;
};

/// Runs `ehlsim <args>` (args already quoted as needed) and captures
/// everything; `launcher` (a command and its options, e.g. setpriv's) runs it.
inline Result ehlsim(const std::string& args, const std::string& launcher = "") {
  const TempDir capture("capture");
  const std::filesystem::path out = capture / "stdout";
  const std::filesystem::path err = capture / "stderr";
  const std::string command = launcher + quote(ehlsim_binary()) + " " + args + " > " +
                              quote(out.string()) + " 2> " + quote(err.string()) + " < /dev/null";
  const int status = std::system(command.c_str());
  Result r;
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  r.out = read_file(out);
  r.err = read_file(err);
  return r;
}

}  // namespace ehlsim::testing
