#include "impact/PressurePredictor.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <initializer_list>
#include <numbers>
#include <stdexcept>
#include <string>
#include <vector>

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

namespace {

/// Where the points of one axis land on the grid when the field is sampled at
/// c times their coordinate: the lower index of the cell (-1: none, beyond
/// the grid or on its outer boundary) and the weight of the upper neighbour.
/// Made once per c, so that a sweep over the grid only interpolates.
struct ContractedAxis {
  std::vector<int> cell;
  std::vector<double> weight;
};

ContractedAxis contracted_axis(const Grid2D& grid, double c, const auto& coordinate) {
  const int n = grid.n;
  const double h = grid.h();
  ContractedAxis axis{std::vector<int>(static_cast<std::size_t>(n), -1),
                      std::vector<double>(static_cast<std::size_t>(n), 0.0)};
  for (int k = 0; k < n; ++k) {
    const bool outer = k == n - 1 || (!grid.mirrored && k == 0);
    const double s = (c * coordinate(k) - coordinate(0)) / h;
    const int k0 = static_cast<int>(std::floor(s));
    if (outer || k0 < 0 || k0 >= n - 1) continue;
    axis.cell[k] = k0;
    axis.weight[k] = s - k0;
  }
  return axis;
}

/// Both axes of `grid` contracted by c.
struct ContractedGrid {
  ContractedAxis x, y;
};

ContractedGrid contracted_grid(const Grid2D& grid, double c) {
  return {contracted_axis(grid, c, [&grid](int i) { return grid.x(i); }),
          contracted_axis(grid, c, [&grid](int j) { return grid.y(j); })};
}

/// field(c x(i), c y(j)) by bilinear interpolation (zero beyond the grid and
/// on its outer boundary).
double contracted_at(const ContractedGrid& at, const Field& field, int i, int j) {
  const int i0 = at.x.cell[static_cast<std::size_t>(i)];
  const int j0 = at.y.cell[static_cast<std::size_t>(j)];
  if (i0 < 0 || j0 < 0) return 0.0;
  const double a = at.x.weight[static_cast<std::size_t>(i)];
  const double b = at.y.weight[static_cast<std::size_t>(j)];
  return (1.0 - b) * ((1.0 - a) * field(i0, j0) + a * field(i0 + 1, j0)) +
         b * ((1.0 - a) * field(i0, j0 + 1) + a * field(i0 + 1, j0 + 1));
}

/// The index range [first, last] of one axis whose coordinates lie within
/// `reach` of the origin, inside the interior.
std::array<int, 2> indices_within(const Grid2D& grid, double reach) {
  const double h = grid.h();
  const int first =
      std::max(grid.first_interior(), static_cast<int>(std::ceil((-reach - grid.x(0)) / h)));
  const int last = std::min(grid.n - 2, static_cast<int>(std::floor((reach - grid.x(0)) / h)));
  return {first, last};
}

/// The largest |X| or |Y| of a point where `a` or `b` is positive.
double pressure_reach(const Grid2D& grid, const Field& a, const Field& b) {
  double reach = 0.0;
  for (int j = 0; j < grid.n; ++j) {
    for (int i = 0; i < grid.n; ++i) {
      if (a(i, j) > 0.0 || b(i, j) > 0.0)
        reach = std::max({reach, std::abs(grid.x(i)), std::abs(grid.y(j))});
    }
  }
  return reach;
}

/// The least-squares misfit of `last` by s times `before` contracted by c,
/// with the best amplitude s for that c, over the full grid (mirror images
/// counted) within `box` x `box`: sum L^2 - (sum L B)^2 / sum B^2, L = last,
/// B = the contracted level.  Row sums on the threads, added in order on one.
double contraction_misfit(const Grid2D& grid, const Field& last, const Field& before, double c,
                          std::array<int, 2> box) {
  struct Sums {
    double last_last = 0.0, last_before = 0.0, before_before = 0.0;
  };
  std::vector<Sums> rows(static_cast<std::size_t>(grid.n));
  const ContractedGrid at = contracted_grid(grid, c);
  const bool threaded = worth_threads(grid);
#pragma omp parallel for schedule(static) if (threaded)
  for (int j = box[0]; j <= box[1]; ++j) {
    Sums row;
    for (int i = box[0]; i <= box[1]; ++i) {
      const double weight = grid.multiplicity(i) * grid.multiplicity(j);
      const double L = last(i, j);
      const double B = contracted_at(at, before, i, j);
      row.last_last += weight * L * L;
      row.last_before += weight * L * B;
      row.before_before += weight * B * B;
    }
    rows[j] = row;
  }
  Sums sum;
  for (int j = box[0]; j <= box[1]; ++j) {
    sum.last_last += rows[j].last_last;
    sum.last_before += rows[j].last_before;
    sum.before_before += rows[j].before_before;
  }
  if (sum.before_before == 0.0) return sum.last_last;
  return sum.last_last - sum.last_before * sum.last_before / sum.before_before;
}

}  // namespace

void contract_radially(const Grid2D& grid, const Field& field, double contraction, Field& out) {
  check_grids("contract_radially", field, {&out});
  if (field.n() != grid.n)
    throw std::invalid_argument("contract_radially: the field is not on the grid");
  const int n = grid.n;
  const ContractedGrid at = contracted_grid(grid, contraction);
#pragma omp parallel for schedule(static) if (worth_threads(grid))
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) out(i, j) = contracted_at(at, field, i, j);
  }
}

double radial_contraction(const Grid2D& grid, const Field& last, const Field& before) {
  check_grids("radial_contraction", last, {&before});
  if (last.n() != grid.n)
    throw std::invalid_argument("radial_contraction: the fields are not on the grid");
  const std::array<int, 2> box =
      indices_within(grid, pressure_reach(grid, last, before) / kMinContraction);
  const auto mismatch = [&](double c) { return contraction_misfit(grid, last, before, c, box); };
  // Golden-section search (Kiefer 1953): each step keeps the part of the
  // bracket that holds the smaller of its two inner values.
  const double shrink = 1.0 / std::numbers::phi;
  double low = kMinContraction;
  double high = kMaxContraction;
  double inner_low = high - shrink * (high - low);
  double inner_high = low + shrink * (high - low);
  double at_low = mismatch(inner_low);
  double at_high = mismatch(inner_high);
  while (high - low > kContractionResolution) {
    if (at_low < at_high) {
      high = inner_high;
      inner_high = inner_low;
      at_high = at_low;
      inner_low = high - shrink * (high - low);
      at_low = mismatch(inner_low);
    } else {
      low = inner_low;
      inner_low = inner_high;
      at_low = at_high;
      inner_high = low + shrink * (high - low);
      at_high = mismatch(inner_high);
    }
  }
  return 0.5 * (low + high);
}

void contracting_frame_extrapolation(const Grid2D& grid, const Field& last,
                                     std::span<const Field* const> earlier, double contraction,
                                     Field& out) {
  if (earlier.empty() || earlier.size() > kMaxEarlierLevels)
    throw std::invalid_argument("contracting_frame_extrapolation: 1 to 3 earlier levels");
  std::vector<Field> seen(earlier.size() + 1, Field(grid));  // the levels in the next step's frame
  contract_radially(grid, last, contraction, seen[0]);
  std::vector<const Field*> seen_earlier;
  double factor = contraction;
  for (std::size_t k = 0; k < earlier.size(); ++k) {
    factor *= contraction;
    contract_radially(grid, *earlier[k], factor, seen[k + 1]);
    seen_earlier.push_back(&seen[k + 1]);
  }
  bounded_series_extrapolation(seen[0], seen_earlier, out);
}

}  // namespace ehlsim
