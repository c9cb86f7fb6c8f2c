#pragma once
// timeseries.csv: one row per time step (StepRecord), written atomically.
#include <cstddef>
#include <filesystem>
#include <fstream>
#include <string_view>

#include "impact/ImpactObserver.hpp"
#include "io/AtomicFile.hpp"

namespace ehlsim {

class TimeSeriesWriter {
 public:
  /// The first line of the file.
  static constexpr std::string_view kHeader =
      "T,Delta,dDelta_dT,force,h_center,h_min,p_center,p_max,cycles,residual";

  /// Opens "<path>.part" and writes the header.  Throws std::runtime_error.
  explicit TimeSeriesWriter(const std::filesystem::path& path);
  TimeSeriesWriter(const TimeSeriesWriter&) = delete;
  TimeSeriesWriter& operator=(const TimeSeriesWriter&) = delete;

  /// One row; numbers with 10 significant digits.
  void append(const StepRecord& record);
  /// Flushes, closes and renames to the final name.
  void commit();
  [[nodiscard]] std::size_t rows() const { return rows_; }
  [[nodiscard]] const std::filesystem::path& path() const { return file_.final_path(); }

 private:
  void check(const char* what) const;

  PartialFile file_;   // declared first: destroyed after the stream is closed
  std::ofstream out_;
  std::size_t rows_ = 0;
};

}  // namespace ehlsim
