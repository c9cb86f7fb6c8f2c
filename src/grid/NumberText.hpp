#pragma once
// A number for a one-line message, or "not finite": "-nan" or "inf" in a
// residual tells the user less than the words do.
#include <fmt/format.h>

#include <cmath>
#include <string>

namespace ehlsim {

/// v formatted by `spec` (e.g. "{:.3e}"), or "not finite".
[[nodiscard]] inline std::string finite_or_text(double v, fmt::format_string<double> spec) {
  return std::isfinite(v) ? fmt::vformat(spec, fmt::make_format_args(v))
                          : std::string("not finite");
}

}  // namespace ehlsim
