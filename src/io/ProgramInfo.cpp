#include "io/ProgramInfo.hpp"

#include <fmt/format.h>
#include <netcdf.h>

#include <string>

#include "ehlsim/Revision.hpp"  // generated at build time (cmake/Revision.cmake)
#include "elastic/Deformation.hpp"

namespace ehlsim {

std::string_view source_revision() { return EHLSIM_REVISION; }

std::string program_text() {
  return fmt::format("ehlsim {} (revision {})", EHLSIM_VERSION, source_revision());
}

namespace {
/// "4.9.0" of nc_inq_libvers()'s "4.9.0 of Aug  7 2022 23:41:41 $".
std::string netcdf_version() {
  const std::string text = nc_inq_libvers();
  return text.substr(0, text.find(' '));
}
}  // namespace

nlohmann::json program_json(std::string_view command) {
  return {{"name", "ehlsim"},
          {"version", EHLSIM_VERSION},
          {"revision", source_revision()},
          {"command", command},
          {"build",
           {{"type", EHLSIM_BUILD_TYPE},
            {"compiler", EHLSIM_COMPILER},
            {"fftw", fft_library_version()},
            {"netcdf", netcdf_version()}}}};
}

}  // namespace ehlsim
