#pragma once
// Where a test finds the source tree, the ehlsim binary and the EIO shim: in
// test-paths.txt beside the test executables (written by tests/CMakeLists.txt),
// not compiled in.  With the paths compiled in, every test object depended on
// where the tree was cloned, and ccache missed all of them when CI cloned
// elsewhere.
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

namespace ehlsim::testing {

/// The value of `key` in test-paths.txt beside this test executable; a test
/// stops with a message where the file or the key is missing.
inline std::string test_path(const std::string& key) {
  const std::filesystem::path file =
      std::filesystem::read_symlink("/proc/self/exe").parent_path() / "test-paths.txt";
  std::ifstream in(file);
  for (std::string line; std::getline(in, line);)
    if (line.rfind(key + "=", 0) == 0) return line.substr(key.size() + 1);
  std::fprintf(stderr, "%s: no %s (build the tests with CMake, which writes it)\n", file.c_str(),
               key.c_str());
  std::exit(2);
}

/// The root of the source tree.
inline std::filesystem::path source_dir() { return test_path("EHLSIM_SOURCE_DIR"); }

/// The ehlsim binary of this build.
inline std::string ehlsim_binary() { return test_path("EHLSIM_BINARY"); }

/// A damaged file that crashes the NetCDF/HDF5 library (tests/fuzz-library-crashes).
inline std::filesystem::path library_crash(const std::string& name) {
  return source_dir() / "tests" / "fuzz-library-crashes" / name;
}

/// The LD_PRELOAD library that injects EIO (tests/support/eio_shim.cpp).
inline std::string eio_shim() { return test_path("EHLSIM_EIO_SHIM"); }

}  // namespace ehlsim::testing
