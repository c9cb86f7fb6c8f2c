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

/// The extrapolation at (i, j) of `last` and the levels before it, a step
/// apart: last plus its backward differences of order 1, 2, ... for as long
/// as each is smaller than the one before (PressurePredictor.hpp).
double series_at(const Field& last, std::span<const Field* const> earlier, int i, int j) {
  const double now = last(i, j);
  const double before = (*earlier[0])(i, j);
  const double first = now - before;
  double extrapolated = now + first;
  if (earlier.size() < 2) return extrapolated;
  const double before2 = (*earlier[1])(i, j);
  const double second = now - 2.0 * before + before2;
  if (!(std::abs(second) < std::abs(first))) return extrapolated;
  extrapolated += second;
  if (earlier.size() < 3) return extrapolated;
  const double third = now - 3.0 * before + 3.0 * before2 - (*earlier[2])(i, j);
  if (std::abs(third) < std::abs(second)) extrapolated += third;
  return extrapolated;
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

void bounded_series_extrapolation(const Field& last, std::span<const Field* const> earlier,
                                  Field& out) {
  if (earlier.empty() || earlier.size() > kMaxEarlierLevels)
    throw std::invalid_argument("bounded_series_extrapolation: 1 to 3 earlier levels");
  for (const Field* level : earlier) check_grids("bounded_series_extrapolation", last, {level});
  check_grids("bounded_series_extrapolation", last, {&out});
  const int n = last.n();
  const Field& before = *earlier[0];
  const bool threaded = worth_threads(last.size());
#pragma omp parallel for schedule(static) if (threaded)
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      out(i, j) = bounded(series_at(last, earlier, i, j), bounds_at(last, before, n, i, j), 1.0);
    }
  }
}

}  // namespace ehlsim
