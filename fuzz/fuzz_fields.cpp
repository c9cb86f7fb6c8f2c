// Fuzzes the fields.nc reader (io/FieldReader.hpp) that `ehlsim spike` uses:
// the bytes are the file.  A bad file must end in a std::runtime_error;
// anything else (a crash, undefined behaviour, another exception, a hang) is a
// finding.
#include <cstddef>
#include <cstdint>
#include <stdexcept>

#include "FuzzFile.hpp"
#include "io/FieldReader.hpp"

namespace {
/// Snapshots read per input: the first and the last cover the index range.
constexpr std::size_t kSnapshotsRead = 2;
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static ehlsim::fuzz::FuzzFile file("fields.nc");
  const auto& path = file.write(data, size);
  try {
    const ehlsim::FieldReader reader(path);
    const std::size_t snapshots = reader.times().size();
    for (std::size_t k = 0; k < kSnapshotsRead && k < snapshots; ++k) {
      const ehlsim::Field P = reader.pressure(k == 0 ? 0 : snapshots - 1);
      if (P.size() != reader.grid().size()) __builtin_trap();
    }
  } catch (const std::runtime_error&) {
    // The documented answer to a bad file.
  }
  return 0;
}
