#include "reynolds/LineRelaxation.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "reynolds/BandSolve.hpp"

namespace ehlsim::reynolds {

namespace {
/// Half-bandwidth of the line systems: the flow terms of a distributive change
/// reach two points along the line; the elastic kernel is truncated there too.
constexpr int kHalfBand = 2;
/// Share of a distributive change taken from each of the four neighbours.
constexpr double kDistribution = 0.25;
/// Passes of the projected line solve; the active set of a line settles in
/// one or two passes in practice.
constexpr int kMaxActiveSetPasses = 4;

struct GridPoint {
  int i, j;
};
/// Point a (1..n-2) of grid line `line`: (a, line) on an X line, (line, a) on a Y line.
GridPoint line_point(LineDirection direction, int line, int a) {
  return direction == LineDirection::X ? GridPoint{a, line} : GridPoint{line, a};
}
}  // namespace

LineRelaxation::LineRelaxation(ReynoldsOperator& op, RelaxationSettings settings)
    : op_(op), settings_(settings), jacobi_change_(op.grid()) {}

void LineRelaxation::relax(Field& P, const Field& f, int sweeps) {
  for (int s = 0; s < sweeps; ++s) {
    const bool along_y = settings_.alternate_directions && s % 2 == 1;
    sweep(P, f, along_y ? LineDirection::Y : LineDirection::X);
  }
}

void LineRelaxation::sweep(Field& P, const Field& f, LineDirection direction) {
  const int n = op_.grid().n;
  long gs = 0, jac = 0;
  const double w = settings_.omega_jacobi * damping_;
  const double w_gs = settings_.omega_gauss_seidel * damping_;
  const Field& d = jacobi_change_;
  // Zebra order: the lines of one colour are independent given the other
  // colour, so they are relaxed in parallel; the coefficients (and with them
  // the elastic deformation) are brought up to date before each colour, so
  // each colour sees every change of the other one, through the flow and the
  // elastic terms alike.
  for (int colour = 0; colour < 2; ++colour) {
    op_.update_coefficients(P);
    jacobi_change_.fill(0.0);
    long colour_jac = 0;
#pragma omp parallel reduction(+ : gs, colour_jac)
    {
      std::vector<double> rhs(n - 2);
      std::vector<char> is_jacobi(n - 2);
#pragma omp for schedule(static)
      for (int line = 1 + colour; line < n - 1; line += 2) {
        relax_line(P, f, line, direction, rhs, is_jacobi);
        for (int a = 1; a < n - 1; ++a) {
          const auto [i, j] = line_point(direction, line, a);
          if (is_jacobi[a - 1]) {
            jacobi_change_(i, j) = rhs[a - 1];
            ++colour_jac;
          } else {
            P(i, j) = std::max(0.0, P(i, j) + w_gs * rhs[a - 1]);
            ++gs;
          }
        }
      }
    }
    jac += colour_jac;
    if (colour_jac == 0) continue;
    // Distributive changes: delta at the point, -delta/4 at each neighbour.
#pragma omp parallel for schedule(static)
    for (int j = 1; j < n - 1; ++j) {
      for (int i = 1; i < n - 1; ++i) {
        const double change =
            d(i, j) - kDistribution * (d(i - 1, j) + d(i + 1, j) + d(i, j - 1) + d(i, j + 1));
        if (change != 0.0) P(i, j) = std::max(0.0, P(i, j) + w * change);
      }
    }
  }
  stats_ = {gs, jac};
}

void LineRelaxation::relax_line(Field& P, const Field& f, int line, LineDirection direction,
                                std::vector<double>& rhs, std::vector<char>& is_jacobi) {
  // Point a = 1..n-2 of the line is line_point(direction, line, a).  The
  // kernel is symmetric, K(d, 0) = K(0, d), so the band of the elastic term is
  // the same for both directions.
  const bool along_x = direction == LineDirection::X;
  const Grid2D& grid = op_.grid();
  const int n = grid.n;
  const int m = n - 2;
  const double h2 = grid.h() * grid.h();
  const double squeeze = op_.squeeze_coefficient();
  const Field& rho = op_.density();
  const Field& drho = op_.density_derivative();
  const Field& H = op_.film();
  const bool elastic = op_.elastic();
  const double k00 = op_.kernel(0, 0);

  // Elastic kernels along the line: plain (a change at one point) and
  // distributed (a change with -1/4 at the four neighbours).
  double kplain[kHalfBand + 1];
  double kdist[kHalfBand + 1];
  for (int d = 0; d <= kHalfBand; ++d) {
    kplain[d] = op_.kernel(d, 0);
    kdist[d] = op_.kernel(d, 0) -
               kDistribution * (op_.kernel(d - 1, 0) + op_.kernel(d + 1, 0) + 2.0 * op_.kernel(d, 1));
  }

  // Face coefficients of the line, divided by h^2: backward and forward
  // along the line (cw, ce), backward and forward across it (cs, cn).
  thread_local std::vector<double> cw, ce, cs, cn;
  cw.resize(m); ce.resize(m); cs.resize(m); cn.resize(m);
  for (int a = 1; a < n - 1; ++a) {
    const auto [i, j] = line_point(direction, line, a);
    const ReynoldsOperator::Faces faces = op_.faces_at(i, j);
    cw[a - 1] = (along_x ? faces.west : faces.south) / h2;
    ce[a - 1] = (along_x ? faces.east : faces.north) / h2;
    cs[a - 1] = (along_x ? faces.south : faces.west) / h2;
    cn[a - 1] = (along_x ? faces.north : faces.east) / h2;
    const double flow = cw[a - 1] + ce[a - 1] + cs[a - 1] + cn[a - 1];
    // Distributive changes also move the four neighbours: next to a cavitated
    // point they would fight the projection, so such points use Gauss-Seidel.
    is_jacobi[a - 1] = elastic && is_pressurized(P, i, j) &&
                       flow < settings_.switch_ratio * squeeze * rho(i, j) * k00;
    rhs[a - 1] = f(i, j) - op_.apply_at(P, i, j, faces);
  }

  // Points with P = 0 whose residual would lower the pressure stay at 0 (the
  // projection).  A line of such points only (the cavitated region, a large
  // part of the domain in contact) has nothing to solve.
  thread_local std::vector<double> fixed_change;
  fixed_change.assign(m, std::numeric_limits<double>::quiet_NaN());
  bool all_fixed = true;
  for (int a = 0; a < m; ++a) {
    const auto [i, j] = line_point(direction, line, a + 1);
    if (P(i, j) <= 0.0 && rhs[a] >= 0.0) {
      fixed_change[a] = 0.0;
    } else {
      all_fixed = false;
    }
  }
  if (all_fixed) {
    std::fill(rhs.begin(), rhs.end(), 0.0);
    return;
  }

  thread_local BandMatrix A(0, kHalfBand);
  if (A.size() != m) A = BandMatrix(m, kHalfBand);
  A.clear();
  // Row a (point i = a + 1): derivative of N_i with respect to the change of column c.
  for (int a = 0; a < m; ++a) {
    const auto [i, j] = line_point(direction, line, a + 1);
    const double elastic_scale = -squeeze * rho(i, j);
    // d N_a / d P at the point itself, its neighbours along the line (flow part).
    const double self = -(cw[a] + ce[a] + cs[a] + cn[a]) - squeeze * drho(i, j) * H(i, j);
    const int first = std::max(0, a - kHalfBand), last = std::min(m - 1, a + kHalfBand);
    for (int c = first; c <= last; ++c) {
      const int d = std::abs(a - c);
      double value = 0.0;
      if (!is_jacobi[c]) {
        // Change e_c.
        if (c == a) value += self;
        if (c == a - 1) value += cw[a];
        if (c == a + 1) value += ce[a];
        value += elastic_scale * kplain[d];
      } else {
        // Change e_c - (e_{c-1} + e_{c+1} + e_{c, j-1} + e_{c, j+1}) / 4.
        if (c == a) value += self - kDistribution * (cs[a] + cn[a]) - kDistribution * (cw[a] + ce[a]);
        if (c == a - 1) value += cw[a] - kDistribution * self;
        if (c == a + 1) value += ce[a] - kDistribution * self;
        if (c == a - 2) value += -kDistribution * cw[a];
        if (c == a + 2) value += -kDistribution * ce[a];
        value += elastic_scale * kdist[d];
      }
      A(a, c) = value;
    }
  }
  // Projected line solve.  A Gauss-Seidel point whose new pressure would be
  // negative is fixed at P = 0 (its change becomes -P / omega) and the line is
  // solved again, so that its neighbours do not count on a change that the
  // projection would undo; a few passes settle the active set.
  const double omega = settings_.omega_gauss_seidel * damping_;
  thread_local BandMatrix work(0, kHalfBand);
  thread_local std::vector<double> residual;
  residual = rhs;
  for (int pass = 0; pass < kMaxActiveSetPasses; ++pass) {
    work = A;
    rhs = residual;
    for (int a = 0; a < m; ++a) {
      if (std::isnan(fixed_change[a])) continue;
      const int first = std::max(0, a - kHalfBand), last = std::min(m - 1, a + kHalfBand);
      for (int c = first; c <= last; ++c) work(a, c) = 0.0;
      work(a, a) = 1.0;
      rhs[a] = fixed_change[a];
      is_jacobi[a] = 0;
    }
    work.solve(rhs);
    bool changed = false;
    for (int a = 0; a < m; ++a) {
      if (is_jacobi[a] || !std::isnan(fixed_change[a])) continue;
      const auto [i, j] = line_point(direction, line, a + 1);
      const double p = P(i, j);
      if (p + omega * rhs[a] < 0.0) {
        fixed_change[a] = -p / omega;
        changed = true;
      }
    }
    if (!changed) break;
  }
}

}  // namespace ehlsim::reynolds
