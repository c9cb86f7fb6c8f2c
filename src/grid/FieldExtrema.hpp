#pragma once
// Where a field is smallest or largest over the interior points of its grid:
// the minimum film and the largest pressure that every mode reports; and the
// first point of a field read from a file that no run could have written.
#include <cmath>
#include <limits>
#include <optional>

#include "grid/Grid.hpp"

namespace ehlsim {

/// A value of a field and the grid point that holds it.
struct PointValue {
  double value = 0.0;
  int i = 0, j = 0;
  double x = 0.0, y = 0.0;
};

/// The first interior point (row by row) where `better(f(i, j), best)` holds
/// against every earlier one.
template <class Better>
[[nodiscard]] PointValue interior_extremum(const Grid2D& grid, const Field& f, double start,
                                           Better better) {
  PointValue best{start};
  for (int j = grid.first_interior(); j < grid.n - 1; ++j) {
    for (int i = grid.first_interior(); i < grid.n - 1; ++i) {
      if (better(f(i, j), best.value)) best = {f(i, j), i, j, grid.x(i), grid.y(j)};
    }
  }
  return best;
}

[[nodiscard]] inline PointValue interior_minimum(const Grid2D& grid, const Field& f) {
  return interior_extremum(grid, f, std::numeric_limits<double>::infinity(),
                           [](double a, double b) { return a < b; });
}

[[nodiscard]] inline PointValue interior_maximum(const Grid2D& grid, const Field& f) {
  return interior_extremum(grid, f, -std::numeric_limits<double>::infinity(),
                           [](double a, double b) { return a > b; });
}

/// The first point of `f` (row by row, all n^2 of them) whose value is not
/// finite, or is negative where `nonnegative_at(i, j)`: what the readers of
/// fields.nc and of a checkpoint refuse.  nullopt when every value is sound.
template <class NonNegativeAt>
[[nodiscard]] std::optional<PointValue> first_unsound_point(const Field& f,
                                                            NonNegativeAt nonnegative_at) {
  for (int j = 0; j < f.n(); ++j) {
    for (int i = 0; i < f.n(); ++i) {
      const double v = f(i, j);
      if (!std::isfinite(v) || (v < 0.0 && nonnegative_at(i, j))) return PointValue{v, i, j};
    }
  }
  return std::nullopt;
}

}  // namespace ehlsim
