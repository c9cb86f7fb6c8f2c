#include "io/TimeSeriesWriter.hpp"

#include <cerrno>
#include <stdexcept>
#include <system_error>

#include <fmt/format.h>

namespace ehlsim {

TimeSeriesWriter::TimeSeriesWriter(const std::filesystem::path& path)
    : file_(path), out_(file_.part_path(), std::ios::binary | std::ios::trunc) {
  check("open");
  out_ << kHeader << '\n';
  check("write");
}

void TimeSeriesWriter::check(const char* what) const {
  if (!out_) {
    throw std::runtime_error(fmt::format("cannot {} '{}': {}", what, file_.part_path().string(),
                                         std::generic_category().message(errno)));
  }
}

void TimeSeriesWriter::append(const StepRecord& r) {
  out_ << fmt::format("{:.10g},{:.10g},{:.10g},{:.10g},{:.10g},{:.10g},{:.10g},{:.10g},{},{:.10g}\n",
                      r.T, r.Delta, r.dDelta_dT, r.force, r.h_center, r.h_min, r.p_center, r.p_max,
                      r.cycles, r.residual);
  check("write");
  ++rows_;
}

void TimeSeriesWriter::commit() {
  if (file_.committed()) return;
  out_.flush();
  check("write");
  out_.close();
  check("close");
  file_.commit();
}

}  // namespace ehlsim
