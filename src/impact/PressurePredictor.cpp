#include "impact/PressurePredictor.hpp"

#include <algorithm>
#include <cmath>
#include <initializer_list>
#include <stdexcept>
#include <string>

namespace ehlsim {

namespace {

/// What bounds the extrapolation at (i, j): the range of `last` over the
/// point and its eight neighbours, and the least change in time among them.
struct Bounds {
  double lowest, highest, least_change;
};
Bounds bounds_at(const Field& last, const Field& before, int n, int i, int j) {
  Bounds b{last(i, j), last(i, j), std::abs(last(i, j) - before(i, j))};
  for (int row = std::max(0, j - 1); row <= std::min(n - 1, j + 1); ++row) {
    for (int a = std::max(0, i - 1); a <= std::min(n - 1, i + 1); ++a) {
      b.lowest = std::min(b.lowest, last(a, row));
      b.highest = std::max(b.highest, last(a, row));
      b.least_change = std::min(b.least_change, std::abs(last(a, row) - before(a, row)));
    }
  }
  return b;
}

double bounded(double extrapolated, const Bounds& b, double omega) {
  const double widening = omega * b.least_change;
  return std::max(0.0, std::clamp(extrapolated, b.lowest - widening, b.highest + widening));
}

/// Throws std::invalid_argument naming `function` unless every field is on the grid of `last`.
void check_grids(const char* function, const Field& last,
                 std::initializer_list<const Field*> others) {
  for (const Field* f : others)
    if (f->n() != last.n())
      throw std::invalid_argument(std::string(function) + ": the fields are on different grids");
}

}  // namespace

void bounded_extrapolation(const Field& last, const Field& before, double omega, Field& out) {
  check_grids("bounded_extrapolation", last, {&before, &out});
  const int n = last.n();
  const bool threaded = worth_threads(last.size());
#pragma omp parallel for schedule(static) if (threaded)
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const double extrapolated = (1.0 + omega) * last(i, j) - omega * before(i, j);
      out(i, j) = bounded(extrapolated, bounds_at(last, before, n, i, j), omega);
    }
  }
}

void bounded_quadratic_extrapolation(const Field& last, const Field& before, const Field& before2,
                                     Field& out) {
  check_grids("bounded_quadratic_extrapolation", last, {&before, &before2, &out});
  const int n = last.n();
  const bool threaded = worth_threads(last.size());
#pragma omp parallel for schedule(static) if (threaded)
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const double first = last(i, j) - before(i, j);
      const double second = last(i, j) - 2.0 * before(i, j) + before2(i, j);
      const double extrapolated =
          std::abs(second) < std::abs(first) ? last(i, j) + first + second : last(i, j) + first;
      out(i, j) = bounded(extrapolated, bounds_at(last, before, n, i, j), 1.0);
    }
  }
}

}  // namespace ehlsim
