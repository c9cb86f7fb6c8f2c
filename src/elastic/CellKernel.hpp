#pragma once
// Influence coefficients of the elastic half-space deformation
//   W(X, Y) = (2/pi^2) Int Int P(X', Y') / |r - r'| dX' dY'
// for a pressure that is constant on each square cell of side h centred at a
// grid point (Love 1929; Johnson, Contact Mechanics, eq. 3.25; model.md).
#include <vector>

#include "grid/Grid.hpp"

namespace ehlsim {

/// Deformation at offset (x, y) from the centre of a cell of side h that
/// carries a uniform unit pressure:
///   K = (2/pi^2)[G(x+, y+) - G(x+, y-) - G(x-, y+) + G(x-, y-)],
///   G(x, y) = x asinh(y/|x|) + y asinh(x/|y|),  x+- = x +- h/2, y+- = y +- h/2.
/// Even in x and y, symmetric in (x, y), and K -> (2/pi^2) h^2 / r far away.
[[nodiscard]] double cell_kernel(double x, double y, double h);

/// K(|di| h, |dj| h, h) for all offsets between two points of a grid,
/// 0 <= |di|, |dj| <= n - 1.  Memory: n^2 doubles.
///
/// The entries are computed in long double on the half-integer lattice of
/// cell corners: the four-term difference above cancels badly far from the
/// cell (G ~ r ln r while K ~ h^2/r): in plain double the far entries of a
/// 1025^2 table are off by up to ~1e-9 relative; extended precision keeps
/// them at ~1e-13.  Cost: (n+1)^2/2 corner values, ~0.1 s for n = 1025.
class KernelTable {
 public:
  explicit KernelTable(const Grid2D& grid);

  [[nodiscard]] double operator()(int di, int dj) const {
    const int a = di < 0 ? -di : di;
    const int b = dj < 0 ? -dj : dj;
    return k_[static_cast<std::size_t>(b) * n_ + a];
  }
  [[nodiscard]] int n() const { return n_; }
  [[nodiscard]] double h() const { return h_; }
  /// Row-major table: entry (a, b), a = |di|, b = |dj|, at b * n + a.
  [[nodiscard]] const double* data() const { return k_.data(); }

 private:
  int n_;
  double h_;
  std::vector<double> k_;
};

}  // namespace ehlsim
