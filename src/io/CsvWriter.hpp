#pragma once
// A CSV file written atomically: "<name>.part" while being written, renamed
// to its final name by commit() (PartialFile); removed if never committed.
#include <cstddef>
#include <filesystem>
#include <fstream>
#include <string_view>

#include "io/AtomicFile.hpp"

namespace ehlsim {

class CsvWriter {
 public:
  /// Opens "<path>.part" and writes the header line.  Throws std::runtime_error.
  CsvWriter(const std::filesystem::path& path, std::string_view header);
  CsvWriter(const CsvWriter&) = delete;
  CsvWriter& operator=(const CsvWriter&) = delete;

  /// One row (without the line end).
  void append(std::string_view row);
  /// Flushes, closes and renames to the final name.
  void commit();
  [[nodiscard]] std::size_t rows() const { return rows_; }
  [[nodiscard]] const std::filesystem::path& path() const { return file_.final_path(); }

 private:
  void check(const char* what) const;

  PartialFile file_;  // declared first: destroyed after the stream is closed
  std::ofstream out_;
  std::size_t rows_ = 0;
};

}  // namespace ehlsim
