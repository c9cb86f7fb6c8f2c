#pragma once
// The readers under test take a path: each execution writes the fuzzer's bytes
// to a new file, in /dev/shm when there is one (no disk traffic).  A new name
// (so a new inode) per execution keeps the inputs independent: HDF5 keeps
// some corrupt files open after nc_open has failed, and a later H5Fopen of
// the same inode would reuse that file's cached metadata instead of reading
// the new bytes (the first "crash" found was such a mix of two inputs).
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
    base_ = dir / ("ehlsim_fuzz_" + tag + "_" + std::to_string(::getpid()) + "_");
  }
  ~FuzzFile() { remove(); }
  FuzzFile(const FuzzFile&) = delete;
  FuzzFile& operator=(const FuzzFile&) = delete;

  /// Removes the previous file and writes `size` bytes from `data` to a new one.
  const std::filesystem::path& write(const std::uint8_t* data, std::size_t size) {
    remove();
    path_ = base_;
    path_ += std::to_string(++executions_);
    std::FILE* file = std::fopen(path_.c_str(), "wb");
    if (file == nullptr) throw std::runtime_error("fuzz: cannot create " + path_.string());
    const bool written = size == 0 || std::fwrite(data, 1, size, file) == size;
    if (std::fclose(file) != 0 || !written)
      throw std::runtime_error("fuzz: cannot write " + path_.string());
    return path_;
  }

 private:
  void remove() {
    std::error_code ec;
    if (!path_.empty()) std::filesystem::remove(path_, ec);
  }

  std::filesystem::path base_;
  std::filesystem::path path_;
  unsigned long long executions_ = 0;
};

}  // namespace ehlsim::fuzz
