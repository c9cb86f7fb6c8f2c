#include "io/CsvWriter.hpp"

#include <fmt/format.h>

#include <cerrno>
#include <stdexcept>
#include <system_error>

namespace ehlsim {

CsvWriter::CsvWriter(const std::filesystem::path& path, std::string_view header)
    : file_(path), out_(file_.part_path(), std::ios::binary | std::ios::trunc) {
  check("open");
  out_ << header << '\n';
  check("write");
}

void CsvWriter::check(const char* what) const {
  if (!out_) {
    throw std::runtime_error(fmt::format("cannot {} '{}': {}", what, file_.part_path().string(),
                                         std::generic_category().message(errno)));
  }
}

void CsvWriter::append(std::string_view row) {
  out_ << row << '\n';
  check("write");
  ++rows_;
}

void CsvWriter::commit() {
  if (file_.committed()) return;
  out_.flush();
  check("write");
  out_.close();
  check("close");
  file_.commit();
}

}  // namespace ehlsim
