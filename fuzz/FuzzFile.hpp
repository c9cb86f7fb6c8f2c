#pragma once
// The readers under test take a path: each execution writes the fuzzer's bytes
// to one file per process, in /dev/shm when there is one (no disk traffic).
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <system_error>

namespace ehlsim::fuzz {

class FuzzFile {
 public:
  explicit FuzzFile(const std::string& tag) {
    std::error_code ec;
    const std::filesystem::path shm = "/dev/shm";
    const auto dir =
        std::filesystem::is_directory(shm, ec) ? shm : std::filesystem::temp_directory_path();
    path_ = dir / ("ehlsim_fuzz_" + tag + "_" + std::to_string(::getpid()));
  }
  ~FuzzFile() {
    std::error_code ec;
    std::filesystem::remove(path_, ec);
  }
  FuzzFile(const FuzzFile&) = delete;
  FuzzFile& operator=(const FuzzFile&) = delete;

  /// Replaces the file's content with `size` bytes from `data`.
  const std::filesystem::path& write(const std::uint8_t* data, std::size_t size) const {
    std::FILE* file = std::fopen(path_.c_str(), "wb");
    if (file == nullptr) throw std::runtime_error("fuzz: cannot create " + path_.string());
    const bool written = size == 0 || std::fwrite(data, 1, size, file) == size;
    if (std::fclose(file) != 0 || !written)
      throw std::runtime_error("fuzz: cannot write " + path_.string());
    return path_;
  }

 private:
  std::filesystem::path path_;
};

}  // namespace ehlsim::fuzz
