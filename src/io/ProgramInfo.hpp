#pragma once
// What produced an output: the program, its source revision and what it was
// built with.  The same input gives the same bits with the same binary
// (docs/usage.md, "Reproducibility"); another revision, compiler, FFTW or CPU
// may round otherwise, so every output says which binary wrote it.
#include <nlohmann/json.hpp>
#include <string>
#include <string_view>

namespace ehlsim {

/// The source revision of this binary: `git describe --always --dirty` of the
/// tree it was built from (a commit, "-dirty" for uncommitted changes), or
/// "unknown" for a tree outside git (cmake/Revision.cmake).
[[nodiscard]] std::string_view source_revision();

/// "ehlsim 0.1.0 (revision 83daeb01298e)": --version and fields.nc's source.
[[nodiscard]] std::string program_text();

/// run.json's and study.json's "program": name, version, revision, `command`
/// and the build (type, compiler, FFTW and NetCDF library versions).
[[nodiscard]] nlohmann::json program_json(std::string_view command);

}  // namespace ehlsim
