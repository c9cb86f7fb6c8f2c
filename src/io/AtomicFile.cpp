#include "io/AtomicFile.hpp"

#include <fcntl.h>
#include <fmt/format.h>
#include <unistd.h>

#include <cerrno>
#include <fstream>
#include <stdexcept>
#include <system_error>
#include <utility>

namespace ehlsim {

namespace {
constexpr int kJsonIndent = 2;
}  // namespace

PartialFile::PartialFile(std::filesystem::path final_path)
    : final_path_(std::move(final_path)), part_path_(final_path_.string() + kSuffix) {}

PartialFile::~PartialFile() {
  if (!committed_) {
    std::error_code ec;  // nothing to report from a destructor
    std::filesystem::remove(part_path_, ec);
  }
}

void sync_path(const std::filesystem::path& path) {
  const int fd = open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0 || fsync(fd) != 0) {
    const int error = errno;
    if (fd >= 0) close(fd);
    throw std::runtime_error(fmt::format("cannot sync '{}' to disk: {}", path.string(),
                                         std::generic_category().message(error)));
  }
  close(fd);
}

void PartialFile::commit() {
  if (committed_) return;
  sync_path(part_path_);
  std::error_code ec;
  std::filesystem::rename(part_path_, final_path_, ec);
  if (ec) {
    throw std::runtime_error(fmt::format("cannot rename '{}' to '{}': {}", part_path_.string(),
                                         final_path_.string(), ec.message()));
  }
  committed_ = true;
}

void write_json_atomic(const std::filesystem::path& path, const nlohmann::json& json) {
  PartialFile file(path);
  {
    std::ofstream out(file.part_path(), std::ios::binary | std::ios::trunc);
    if (!out) {
      throw std::runtime_error(fmt::format("cannot write '{}': {}", file.part_path().string(),
                                           std::generic_category().message(errno)));
    }
    // A path that is no UTF-8 (--out $'o\x80') made dump() throw after the
    // run, and the run was lost: such bytes are written as U+FFFD.
    out << json.dump(kJsonIndent, ' ', false, nlohmann::json::error_handler_t::replace) << '\n';
    out.close();
    if (!out) {
      throw std::runtime_error(fmt::format("cannot write '{}': {}", file.part_path().string(),
                                           std::generic_category().message(errno)));
    }
  }
  file.commit();
}

}  // namespace ehlsim
