#include "elastic/CellKernel.hpp"

#include <cmath>
#include <numbers>

namespace ehlsim {
namespace {

/// Prefactor of the dimensionless half-space operator, 2/pi^2 (model.md).
template <class Real>
constexpr Real kElasticPrefactor = Real{2} / (std::numbers::pi_v<Real> * std::numbers::pi_v<Real>);

/// One term x asinh(y/|x|); its limit for x -> 0 is 0 (x ln|x| -> 0), which
/// is also the value the 0/0 would need on a cell edge.
template <class Real>
Real g_term(Real x, Real y) {
  if (x == Real{0}) return Real{0};
  return x * std::asinh(y / std::fabs(x));
}

template <class Real>
Real G(Real x, Real y) {
  return g_term(x, y) + g_term(y, x);
}

}  // namespace

double cell_kernel(double x, double y, double h) {
  const double half = 0.5 * h;
  const double xp = x + half, xm = x - half, yp = y + half, ym = y - half;
  return kElasticPrefactor<double> * (G(xp, yp) - G(xp, ym) - G(xm, yp) + G(xm, ym));
}

KernelTable::KernelTable(const Grid2D& grid) : n_(grid.n), h_(grid.h()), k_(grid.size()) {
  using Real = long double;
  // G is homogeneous of degree 1, so K(a h, b h, h) = h K(a, b, 1): work in
  // units of h on the corner lattice c = a - 1/2, a = 0..n, and share each G
  // between the four cells that meet at that corner.
  const int nc = n_ + 1;
  std::vector<Real> g(static_cast<std::size_t>(nc) * nc);
  for (int b = 0; b < nc; ++b) {
    for (int a = 0; a <= b; ++a) {  // G(x, y) = G(y, x)
      const Real value = G(static_cast<Real>(a) - Real{0.5}, static_cast<Real>(b) - Real{0.5});
      g[static_cast<std::size_t>(b) * nc + a] = value;
      g[static_cast<std::size_t>(a) * nc + b] = value;
    }
  }
  const Real scale = kElasticPrefactor<Real> * static_cast<Real>(h_);
  for (int b = 0; b < n_; ++b) {
    const Real* lo = &g[static_cast<std::size_t>(b) * nc];  // y- = b - 1/2
    const Real* hi = lo + nc;                               // y+ = b + 1/2
    for (int a = 0; a < n_; ++a) {
      const Real sum = hi[a + 1] - lo[a + 1] - hi[a] + lo[a];
      k_[static_cast<std::size_t>(b) * n_ + a] = static_cast<double>(scale * sum);
    }
  }
}

}  // namespace ehlsim
