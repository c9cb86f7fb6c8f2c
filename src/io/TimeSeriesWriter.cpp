#include "io/TimeSeriesWriter.hpp"

#include <fmt/format.h>

namespace ehlsim {

void TimeSeriesWriter::append(const StepRecord& r) {
  csv_.append(fmt::format(
      "{:.10g},{:.10g},{:.10g},{:.10g},{:.10g},{:.10g},{:.10g},{:.10g},{},{:.10g},{},{:.6g}", r.T,
      r.Delta, r.dDelta_dT, r.force, r.h_center, r.h_min, r.p_center, r.p_max, r.cycles, r.residual,
      r.attempts, r.work));
}

}  // namespace ehlsim
