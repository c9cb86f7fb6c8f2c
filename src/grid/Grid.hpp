#pragma once
// Uniform square grid and the fields that live on it.
//
// The domain is [-half_width, half_width]^2 with n points per side (boundary
// points included), so the mesh size is h = 2 half_width / (n - 1).  A field is
// stored row-major: value (i, j) at index j * n + i, i along X, j along Y.
#include <algorithm>
#include <cstddef>
#include <span>
#include <stdexcept>
#include <vector>

namespace ehlsim {

struct Grid2D {
  int n = 0;                 ///< points per side, boundary included
  double half_width = 0.0;   ///< the domain is [-half_width, half_width]^2

  Grid2D() = default;
  Grid2D(int points, double half) : n(points), half_width(half) {
    if (points < 3) throw std::invalid_argument("Grid2D: need at least 3 points per side");
    if (!(half > 0.0)) throw std::invalid_argument("Grid2D: half_width must be positive");
  }

  [[nodiscard]] double h() const { return 2.0 * half_width / (n - 1); }
  [[nodiscard]] double x(int i) const { return -half_width + i * h(); }
  [[nodiscard]] double y(int j) const { return x(j); }
  [[nodiscard]] std::size_t size() const { return static_cast<std::size_t>(n) * n; }
  [[nodiscard]] std::size_t index(int i, int j) const {
    return static_cast<std::size_t>(j) * n + i;
  }
  /// True when the grid can be coarsened once more by standard coarsening.
  [[nodiscard]] bool coarsenable() const { return n >= 5 && (n - 1) % 2 == 0; }
  /// The grid with every second point (same domain, twice the mesh size).
  [[nodiscard]] Grid2D coarser() const { return Grid2D((n - 1) / 2 + 1, half_width); }
};

/// True for n = 2^k + 1 with k >= 2.
[[nodiscard]] inline bool is_power_of_two_plus_one(long n) {
  if (n < 5) return false;
  const long m = n - 1;
  return (m & (m - 1)) == 0;
}

/// A scalar field on a Grid2D (row-major, j * n + i).
class Field {
 public:
  Field() = default;
  explicit Field(const Grid2D& grid, double value = 0.0)
      : n_(grid.n), data_(grid.size(), value) {}

  [[nodiscard]] int n() const { return n_; }
  [[nodiscard]] std::size_t size() const { return data_.size(); }
  double& operator()(int i, int j) { return data_[static_cast<std::size_t>(j) * n_ + i]; }
  double operator()(int i, int j) const { return data_[static_cast<std::size_t>(j) * n_ + i]; }
  double& operator[](std::size_t k) { return data_[k]; }
  double operator[](std::size_t k) const { return data_[k]; }
  [[nodiscard]] double* data() { return data_.data(); }
  [[nodiscard]] const double* data() const { return data_.data(); }
  [[nodiscard]] std::span<double> span() { return data_; }
  [[nodiscard]] std::span<const double> span() const { return data_; }
  void fill(double value) { std::fill(data_.begin(), data_.end(), value); }

 private:
  int n_ = 0;
  std::vector<double> data_;
};

}  // namespace ehlsim
