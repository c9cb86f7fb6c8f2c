#pragma once
// Where a field is smallest or largest over the interior points of its grid:
// the minimum film and the largest pressure that every mode reports.
#include <limits>

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

}  // namespace ehlsim
