#pragma once
// timeseries.csv: one row per time step (StepRecord), written atomically.
#include <cstddef>
#include <filesystem>
#include <string_view>

#include "impact/ImpactObserver.hpp"
#include "io/CsvWriter.hpp"

namespace ehlsim {

class TimeSeriesWriter {
 public:
  /// The first line of the file.
  static constexpr std::string_view kHeader =
      "T,Delta,dDelta_dT,force,h_center,h_min,p_center,p_max,cycles,residual,attempts,work";

  /// Opens "<path>.part" and writes the header.  Throws std::runtime_error.
  explicit TimeSeriesWriter(const std::filesystem::path& path) : csv_(path, kHeader) {}

  /// One row; numbers with 10 significant digits.
  void append(const StepRecord& record);
  /// Flushes, closes and renames to the final name.
  void commit() { csv_.commit(); }
  [[nodiscard]] std::size_t rows() const { return csv_.rows(); }
  [[nodiscard]] const std::filesystem::path& path() const { return csv_.path(); }

 private:
  CsvWriter csv_;
};

}  // namespace ehlsim
