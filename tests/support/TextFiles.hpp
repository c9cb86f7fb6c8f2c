#pragma once
// Whole text files, written and read back by the tests.
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

namespace ehlsim::testing {

inline std::filesystem::path write_file(const std::filesystem::path& path,
                                        const std::string& text) {
  std::ofstream(path) << text;
  return path;
}

/// The file's contents ("" when it cannot be read).
inline std::string read_file(const std::filesystem::path& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

}  // namespace ehlsim::testing
