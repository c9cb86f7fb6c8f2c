#pragma once
// Uniform square grids and the fields that live on them.
//
// A full grid covers the square of side 2 half_width centred on (x_center,
// y_center) with n points per side (boundary points included), so the mesh
// size is h = 2 half_width / (n - 1).  The impact's square is centred on the
// contact; the rolling contact's extends further upstream (X < 0) than
// downstream.
//
// A mirrored grid covers the quadrant [0, half_width]^2 of a problem that is
// even in X and in Y: n points per side, point 0 on the symmetry axis,
// h = half_width / (n - 1).  It stands for the full grid of 2n - 1 points with
// the same mesh size (full()).  Only the far edges i = n - 1 and j = n - 1 are
// boundary; the points on the axes are unknowns, and their neighbours across an
// axis are the mirror images: a Field returns value (|i|, |j|) for negative
// indices, so a stencil at i = 0 reads P(-1, j) = P(1, j) without a special
// case.
//
// A field is stored row-major: value (i, j) at index j * n + i, i along X, j along Y.
#include <algorithm>
#include <cstddef>
#include <cstdlib>
#include <span>
#include <stdexcept>
#include <vector>

namespace ehlsim {

/// Grid sizes the solver accepts: 2^k + 1 between these bounds.
inline constexpr int kMinGridPoints = 9;
inline constexpr int kMaxGridPoints = 4097;

/// The centre of a full grid's square.
struct GridCenter {
  double x = 0.0;
  double y = 0.0;
  bool operator==(const GridCenter&) const = default;
};

struct Grid2D {
  int n = 0;  ///< points per side, boundary included
  /// Half the side of the square (mirrored: the side of the quadrant).
  double half_width = 0.0;
  bool mirrored = false;  ///< the quadrant of a problem even in X and Y
  GridCenter center;      ///< (0, 0) on a mirrored grid

  Grid2D() = default;
  bool operator==(const Grid2D&) const = default;
  Grid2D(int points, double half, bool mirror = false, GridCenter centre = {})
      : n(points), half_width(half), mirrored(mirror), center(centre) {
    if (points < 3) throw std::invalid_argument("Grid2D: need at least 3 points per side");
    if (!(half > 0.0)) throw std::invalid_argument("Grid2D: half_width must be positive");
    if (mirror && (centre.x != 0.0 || centre.y != 0.0))
      throw std::invalid_argument("Grid2D: a mirrored grid is centred on the symmetry axes");
  }

  [[nodiscard]] double h() const { return (mirrored ? 1.0 : 2.0) * half_width / (n - 1); }
  [[nodiscard]] double x(int i) const { return (mirrored ? 0.0 : center.x - half_width) + i * h(); }
  [[nodiscard]] double y(int j) const { return (mirrored ? 0.0 : center.y - half_width) + j * h(); }
  [[nodiscard]] std::size_t size() const { return static_cast<std::size_t>(n) * n; }
  [[nodiscard]] std::size_t index(int i, int j) const {
    return static_cast<std::size_t>(j) * n + i;
  }
  /// The first interior index along each axis: 0 on a mirrored grid (the
  /// axis), 1 on a full grid.  The last one is n - 2 on both.
  [[nodiscard]] int first_interior() const { return mirrored ? 0 : 1; }
  /// How many points of the full grid the point with index i stands for
  /// along one axis: 2 off the axis of a mirrored grid (i and -i), else 1.
  [[nodiscard]] double multiplicity(int i) const { return mirrored && i > 0 ? 2.0 : 1.0; }
  /// Interior points per side of the full grid this grid stands for.
  [[nodiscard]] int full_interior() const { return (mirrored ? 2 * n - 1 : n) - 2; }
  /// The full grid this grid stands for (itself when not mirrored).
  [[nodiscard]] Grid2D full() const { return mirrored ? Grid2D(2 * n - 1, half_width) : *this; }
  /// The mirrored quadrant of a full grid with an odd number of points.
  [[nodiscard]] Grid2D quadrant() const { return Grid2D((n - 1) / 2 + 1, half_width, true); }
  /// True when the grid can be coarsened once more by standard coarsening.
  [[nodiscard]] bool coarsenable() const { return n >= 5 && (n - 1) % 2 == 0; }
  /// The grid with every second point (same domain, twice the mesh size).
  [[nodiscard]] Grid2D coarser() const {
    return Grid2D((n - 1) / 2 + 1, half_width, mirrored, center);
  }
};

/// Grids with fewer points than this run their point loops on one thread:
/// below it, the barrier at the end of a parallel loop costs more than the
/// loop (the coarse multigrid levels; measured: OpenMP's waiting took a fifth
/// of the samples of a 257^2 run when every level ran threaded).
inline constexpr std::size_t kMinPointsForThreads = 64 * 64;

/// True when a point loop over `points` points is worth sharing between threads.
[[nodiscard]] inline bool worth_threads(std::size_t points) {
  return points >= kMinPointsForThreads;
}

/// True when the point loops of `grid` are worth sharing between threads.
[[nodiscard]] inline bool worth_threads(const Grid2D& grid) { return worth_threads(grid.size()); }

/// The sum of value(i, j) over the interior points of the full grid that
/// `grid` stands for: on a mirrored grid each point counts once per image (1
/// at the centre, 2 on an axis, 4 elsewhere).  The rows are summed on the
/// threads and the row sums in order on one, so the bits do not depend on the
/// number of threads.  `value` must be safe to call from several threads.
template <class Value>
[[nodiscard]] double full_interior_sum(const Grid2D& grid, Value&& value) {
  const int n = grid.n;
  const int first = grid.first_interior();
  std::vector<double> rows(static_cast<std::size_t>(n), 0.0);
  const bool threaded = worth_threads(grid);
#pragma omp parallel for schedule(static) if (threaded)
  for (int j = first; j < n - 1; ++j) {
    double row = 0.0;
    for (int i = first; i < n - 1; ++i) row += grid.multiplicity(i) * value(i, j);
    rows[j] = grid.multiplicity(j) * row;
  }
  double sum = 0.0;
  for (int j = first; j < n - 1; ++j) sum += rows[j];
  return sum;
}

/// True for n = 2^k + 1 with k >= 2.
[[nodiscard]] inline bool is_power_of_two_plus_one(long n) {
  if (n < 5) return false;
  const long m = n - 1;
  return (m & (m - 1)) == 0;
}

/// op(k) for every element k of a field of `size` elements, shared between
/// the threads on large grids.  Each element is written by one thread, so the
/// bits do not depend on the number of threads.
template <class Op>
void for_each_element(std::size_t size, Op&& op) {
#pragma omp parallel for schedule(static) if (worth_threads(size))
  for (std::size_t k = 0; k < size; ++k) op(k);
}

/// A scalar field on a Grid2D (row-major, j * n + i).  Negative indices read
/// and write the mirror image (|i|, |j|): on a mirrored grid that is the value
/// across the symmetry axis; a full grid never uses them.
class Field {
 public:
  Field() = default;
  explicit Field(const Grid2D& grid, double value = 0.0)
      : n_(grid.n), first_(grid.first_interior()), data_(grid.size(), value) {}

  [[nodiscard]] int n() const { return n_; }
  /// Grid2D::first_interior() of the grid the field was made on.
  [[nodiscard]] int first_interior() const { return first_; }
  [[nodiscard]] std::size_t size() const { return data_.size(); }
  double& operator()(int i, int j) { return data_[at(i, j)]; }
  double operator()(int i, int j) const { return data_[at(i, j)]; }
  double& operator[](std::size_t k) { return data_[k]; }
  double operator[](std::size_t k) const { return data_[k]; }
  [[nodiscard]] double* data() { return data_.data(); }
  [[nodiscard]] const double* data() const { return data_.data(); }
  [[nodiscard]] std::span<double> span() { return data_; }
  [[nodiscard]] std::span<const double> span() const { return data_; }
  void fill(double value) {
    for_each_element(data_.size(), [&](std::size_t k) { data_[k] = value; });
  }

 private:
  [[nodiscard]] std::size_t at(int i, int j) const {
    return static_cast<std::size_t>(std::abs(j)) * n_ + static_cast<std::size_t>(std::abs(i));
  }

  int n_ = 0;
  int first_ = 1;
  std::vector<double> data_;
};

/// u += v.
inline void add_to(const Field& v, Field& u) {
  for_each_element(u.size(), [&](std::size_t k) { u[k] += v[k]; });
}

/// u = v (u has v's size).
inline void copy_into(const Field& v, Field& u) {
  for_each_element(u.size(), [&](std::size_t k) { u[k] = v[k]; });
}

/// Whether a and b (of one size) hold the same values.  A thread stops
/// reading at its first difference; rows are dealt round-robin, so that every
/// thread meets the contact (where two pressures differ) in its first rows:
/// with halves, the thread of a quadrant's outer half, where both pressures
/// are zero, reads all of it while the other waits.
[[nodiscard]] inline bool equal_values(const Field& a, const Field& b) {
  bool equal = true;
  const std::size_t size = a.size();
  const auto row = static_cast<std::size_t>(std::max(a.n(), 1));
#pragma omp parallel for schedule(static, row) reduction(&& : equal) if (worth_threads(size))
  for (std::size_t k = 0; k < size; ++k) equal = equal && a[k] == b[k];
  return equal;
}

/// out = a - b.
inline void difference(const Field& a, const Field& b, Field& out) {
  for_each_element(out.size(), [&](std::size_t k) { out[k] = a[k] - b[k]; });
}

/// The full-grid field of a field on a mirrored grid (P(-i, j) = P(i, j) ...);
/// a copy of `f` when the grid is full.
[[nodiscard]] inline Field unfold(const Field& f, const Grid2D& grid) {
  if (!grid.mirrored) return f;
  const Grid2D full = grid.full();
  const int c = grid.n - 1;  // the full grid's centre index
  Field out(full);
  for (int j = 0; j < full.n; ++j)
    for (int i = 0; i < full.n; ++i) out(i, j) = f(i - c, j - c);
  return out;
}

/// The quadrant of a full-grid field on the mirrored grid `grid` (a copy when
/// the grid is full).  `f` must have grid.full().n points per side.
[[nodiscard]] inline Field fold(const Field& f, const Grid2D& grid) {
  if (!grid.mirrored) return f;
  const int c = grid.n - 1;
  Field out(grid);
  for (int j = 0; j < grid.n; ++j)
    for (int i = 0; i < grid.n; ++i) out(i, j) = f(i + c, j + c);
  return out;
}

}  // namespace ehlsim
