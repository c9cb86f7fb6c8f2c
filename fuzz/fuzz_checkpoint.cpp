// Fuzzes the checkpoint reader (io/Checkpoint.hpp): the bytes are the file
// given to `ehlsim impact --restart`.  A bad file must end in a
// std::runtime_error (which the command turns into exit 2); anything else (a
// crash, undefined behaviour, another exception, a hang) is a finding.
#include <cstddef>
#include <cstdint>
#include <stdexcept>

#include "FuzzFile.hpp"
#include "io/Checkpoint.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static ehlsim::fuzz::FuzzFile file("checkpoint.nc");
  const auto& path = file.write(data, size);
  try {
    const ehlsim::Checkpoint checkpoint = ehlsim::read_checkpoint(path);
    // What a restart does next: compare the parameters with the run's own.
    ehlsim::check_restart_compatible(checkpoint.parameters, checkpoint.parameters, path.string());
  } catch (const std::runtime_error&) {
    // The documented answer to a bad file (ConfigError is one too).
  }
  return 0;
}
