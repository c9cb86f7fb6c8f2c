#include "impact/PressurePredictor.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace ehlsim {

namespace {

/// The bounded extrapolation at one point (i, j) of an n x n field.
double bounded_at(const Field& last, const Field& before, double omega, int n, int i, int j) {
  double lowest = last(i, j);
  double highest = lowest;
  double least_change = std::abs(lowest - before(i, j));
  for (int b = std::max(0, j - 1); b <= std::min(n - 1, j + 1); ++b) {
    for (int a = std::max(0, i - 1); a <= std::min(n - 1, i + 1); ++a) {
      lowest = std::min(lowest, last(a, b));
      highest = std::max(highest, last(a, b));
      least_change = std::min(least_change, std::abs(last(a, b) - before(a, b)));
    }
  }
  const double widening = omega * least_change;
  const double extrapolated = (1.0 + omega) * last(i, j) - omega * before(i, j);
  return std::max(0.0, std::clamp(extrapolated, lowest - widening, highest + widening));
}

}  // namespace

void bounded_extrapolation(const Field& last, const Field& before, double omega, Field& out) {
  const int n = last.n();
  if (before.n() != n || out.n() != n)
    throw std::invalid_argument("bounded_extrapolation: the fields are on different grids");
  const bool threaded = worth_threads(last.size());
#pragma omp parallel for schedule(static) if (threaded)
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) out(i, j) = bounded_at(last, before, omega, n, i, j);
}

}  // namespace ehlsim
