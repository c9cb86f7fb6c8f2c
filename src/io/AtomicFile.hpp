#pragma once
// Output that is never left half-written: a file is written under the
// temporary name "<name>.part", synced to disk and renamed to its final name
// by commit() (rename is atomic within one file system).  A PartialFile destroyed without
// commit() removes the partial file.
#include <filesystem>
#include <nlohmann/json.hpp>

namespace ehlsim {

class PartialFile {
 public:
  /// Suffix of the temporary name.
  static constexpr const char* kSuffix = ".part";

  explicit PartialFile(std::filesystem::path final_path);
  ~PartialFile();
  PartialFile(const PartialFile&) = delete;
  PartialFile& operator=(const PartialFile&) = delete;

  [[nodiscard]] const std::filesystem::path& final_path() const { return final_path_; }
  /// Where to write until commit().
  [[nodiscard]] const std::filesystem::path& part_path() const { return part_path_; }
  /// Syncs the partial file to disk and renames it to its final name (the
  /// file must be closed).
  void commit();
  [[nodiscard]] bool committed() const { return committed_; }

 private:
  std::filesystem::path final_path_;
  std::filesystem::path part_path_;
  bool committed_ = false;
};

/// fsync(2) of a file or directory; throws std::runtime_error naming it.
void sync_path(const std::filesystem::path& path);

/// Writes `json` (indented) to `path` via "<path>.part" and a rename.
/// Throws std::runtime_error when the file cannot be written.
void write_json_atomic(const std::filesystem::path& path, const nlohmann::json& json);

}  // namespace ehlsim
