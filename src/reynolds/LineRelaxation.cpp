#include "reynolds/LineRelaxation.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "reynolds/BandSolve.hpp"

namespace ehlsim::reynolds {

namespace {
/// Share of a distributive change taken from each of the four neighbours.
constexpr double kDistribution = 0.25;
/// Passes of the projected line solve; the active set of a line settles in
/// one or two passes in practice.
constexpr int kMaxActiveSetPasses = 4;
/// A Gauss-Seidel point whose flow term is below this times the switch's bound
/// (switch_ratio times the elastic term) is elastically coupled: its line
/// system holds only the along-line part of the elastic coupling, so it needs
/// a deformation that is up to date.  Measured on 65^2 (M = 100): L = 0 has
/// 3.7 such points per distributive point and stalls with the deformation once
/// per sweep, L = 10 has 0.3 and converges as with it before each colour.
constexpr double kCoupledGaussSeidelFactor = 10.0;

struct GridPoint {
  int i, j;
};
/// Point a (first interior..n-2) of grid line `line`: (a, line) on an X line, (line, a) on a Y
/// line.
GridPoint line_point(LineDirection direction, int line, int a) {
  return direction == LineDirection::X ? GridPoint{a, line} : GridPoint{line, a};
}
}  // namespace

double switch_ratio_on(const RelaxationSettings& settings, double h) {
  if (settings.switch_reference_mesh <= h) return settings.switch_ratio;
  return settings.switch_ratio * settings.switch_reference_mesh / h;
}

LineRelaxation::LineRelaxation(ReynoldsOperator& op, RelaxationSettings settings)
    : op_(op), settings_(settings), jacobi_change_(op.grid()) {
  settings_.switch_ratio = switch_ratio_on(settings, op.grid().h());
  // Elastic kernels between points `a` meshes apart along a line and `c`
  // across it: of a plain change at one point, and of a distributed one (-1/4
  // at the four neighbours).  K is even in both offsets.
  for (int a = 0; a <= kMaxAlong; ++a) {
    for (int c = 0; c <= kMaxAcross; ++c) {
      kernel_plain_[a][c] = op_.kernel(a, c);
      kernel_distributed_[a][c] =
          op_.kernel(a, c) - kDistribution * (op_.kernel(a - 1, c) + op_.kernel(a + 1, c) +
                                              (op_.kernel(a, c - 1) + op_.kernel(a, c + 1)));
    }
  }
}

/// The transport part of one row of a line system: the points upstream of
/// the row's point whose rho H its equation holds (ReynoldsOperator::taps_at).
struct LineRelaxation::RowTransport {
  LineDirection direction;
  /// -weight[t] rho at tap t: times the kernel, the derivative of the row's
  /// transport term with respect to a pressure change.
  std::array<double, kTransportTaps> elastic_scale{};
  /// -weight[t] (d rho / d P) H at tap t, for t >= 1 (t = 0 is in `self`).
  std::array<double, kTransportTaps> density_scale{};
};

/// The work arrays of one line (one set per thread): `count` unknowns.
struct LineRelaxation::LineWork {
  explicit LineWork(int count)
      : rhs(count),
        cw(count),
        ce(count),
        cs(count),
        cn(count),
        fixed_change(count),
        residual(count),
        omega(count),
        is_jacobi(count),
        A(count, kHalfBand),
        work(count, kHalfBand) {}
  std::vector<double> rhs;             ///< residual in, the line's changes out
  std::vector<double> cw, ce, cs, cn;  ///< face coefficients / h^2: back, forward, across
  std::vector<double> fixed_change;    ///< NaN, or the change a projected point is held to
  std::vector<double> residual;
  std::vector<double> omega;  ///< under-relaxation of a Gauss-Seidel row's change (damped)
  std::vector<char> is_jacobi;
  BandMatrix A, work;
  /// Elastically coupled Gauss-Seidel points and distributive points of the
  /// line, each counted as often as it stands on the full grid (a mirrored
  /// grid's points off the axes stand for two or four), so that the quadrant
  /// makes the full domain's choices.
  long coupled_gauss_seidel = 0, distributive = 0;
};

void LineRelaxation::relax(Field& P, const Field& f, int sweeps) {
  for (int s = 0; s < sweeps; ++s) {
    const bool along_y = settings_.alternate_directions && s % 2 == 1;
    sweep(P, f, along_y ? LineDirection::Y : LineDirection::X);
  }
}

void LineRelaxation::sweep(Field& P, const Field& f, LineDirection direction) {
  // Zebra order: the lines of one colour are independent given the other
  // colour, so they are relaxed in parallel; the coefficients are brought up
  // to date before each colour, so each colour sees every change of the other
  // one through the flow terms, and, before colour 0, through the elastic
  // deformation too.  Before colour 1 the deformation is recomputed only when
  // settings_.deformation_each_colour asks for it, or when colour 0 had more
  // elastically coupled Gauss-Seidel points than distributive ones (they need
  // it, kCoupledGaussSeidelFactor); else colour 1 sees colour 0's elastic
  // effect from the next sweep on.
  SweepStats stats;
  bool refresh_deformation = true;
  for (int colour = 0; colour < 2; ++colour) {
    if (refresh_deformation) {
      op_.update_coefficients(P);
    } else {
      op_.update_coefficients_keeping_deformation(P);
    }
    const ColourResult result = relax_colour(P, f, direction, colour);
    stats.gauss_seidel_points += result.gauss_seidel;
    stats.jacobi_points += result.jacobi;
    // Integer counts: the same choice for every thread count.
    refresh_deformation =
        settings_.deformation_each_colour || result.coupled_gauss_seidel > result.distributive;
    if (result.jacobi > 0) apply_distributive_changes(P, result.jacobi_box);
  }
  stats_ = stats;
}

LineRelaxation::ColourResult LineRelaxation::relax_colour(Field& P, const Field& f,
                                                          LineDirection direction, int colour) {
  const Grid2D& grid = op_.grid();
  const int n = grid.n;
  const int first = grid.first_interior();
  const int m = n - 1 - first;
  long gs = 0, jac = 0, coupled = 0, distributive = 0;
  int i0 = n, i1 = -1, j0 = n, j1 = -1;
  // Colour 0 is the odd lines: on a mirrored grid, whose index 0 is the full
  // grid's even centre line, the lines keep the colours they have on the
  // full grid.
  const int first_line = colour == 0 ? 1 : (first == 0 ? 0 : 2);
  const std::vector<RowRange> candidates =
      direction == LineDirection::Y ? y_line_candidates(P, f, first_line) : std::vector<RowRange>{};
#pragma omp parallel reduction(+ : gs, jac, coupled, distributive) \
    reduction(min : i0, j0) reduction(max : i1, j1) if (worth_threads(grid))
  {
    LineWork line_work(m);
    // Lines round-robin: on the quadrant the contact (the costly lines)
    // lies at one end, and blocks of lines would give it all to one thread.
#pragma omp for schedule(static, 1)
    for (int line = first_line; line < n - 1; line += 2) {
      const RowRange candidate_rows = candidates.empty() ? RowRange{0, m - 1} : candidates[line];
      const RowRange rows = relax_line(P, f, line, direction, candidate_rows, line_work);
      coupled += line_work.coupled_gauss_seidel;
      distributive += line_work.distributive;
      // The held points beyond `rows` keep P = 0: Gauss-Seidel points without a change.
      gs += m - std::max(0, rows.last - rows.first + 1);
      for (int r = rows.first; r <= rows.last; ++r) {
        const auto [i, j] = line_point(direction, line, r + first);
        const double change = line_work.rhs[r];
        if (line_work.is_jacobi[r]) {
          jacobi_change_(i, j) = change;
          i0 = std::min(i0, i), i1 = std::max(i1, i), j0 = std::min(j0, j), j1 = std::max(j1, j);
          ++jac;
        } else {
          P(i, j) = std::max(0.0, P(i, j) + line_work.omega[r] * change);
          ++gs;
        }
      }
    }
  }
  return {gs, jac, coupled, distributive, {i0, i1, j0, j1}};
}

void LineRelaxation::apply_distributive_changes(Field& P, PointBox box) {
  // delta at the point, -delta/4 at each neighbour (across a symmetry axis the
  // neighbour is the mirror image, whose change equals the point's own).  The
  // changes reach one point beyond the box of the distributive points; the
  // box is cleared after, for the next colour.
  const Grid2D& grid = op_.grid();
  const int first = grid.first_interior();
  const int last = grid.n - 2;
  const double w = settings_.omega_jacobi * damping_;
  Field& d = jacobi_change_;
  const bool threaded = worth_threads(grid);
#pragma omp parallel for schedule(static) if (threaded)
  for (int j = std::max(first, box.j0 - 1); j <= std::min(last, box.j1 + 1); ++j) {
    for (int i = std::max(first, box.i0 - 1); i <= std::min(last, box.i1 + 1); ++i) {
      const double change =
          d(i, j) - kDistribution * (d(i - 1, j) + d(i + 1, j) + d(i, j - 1) + d(i, j + 1));
      if (change != 0.0) P(i, j) = std::max(0.0, P(i, j) + w * change);
    }
  }
#pragma omp parallel for schedule(static) if (threaded)
  for (int j = box.j0; j <= box.j1; ++j)
    for (int i = box.i0; i <= box.i1; ++i) d(i, j) = 0.0;
}

bool LineRelaxation::is_held_without_faces(const Field& P, const Field& f, int i, int j) const {
  return is_cavitated_around(P, i, j) && f(i, j) - op_.cavitated_apply_at(i, j) >= 0.0;
}

std::vector<LineRelaxation::RowRange> LineRelaxation::y_line_candidates(const Field& P,
                                                                        const Field& f,
                                                                        int first_line) const {
  // Row by row of the grid, each thread a block of the lines: along a Y line
  // the points lie a grid row apart, and every point would read a new cache
  // line and page of P, f, rho and H.
  const Grid2D& grid = op_.grid();
  const int n = grid.n;
  const int first = grid.first_interior();
  const int m = n - 1 - first;
  std::vector<RowRange> ranges(static_cast<std::size_t>(n), RowRange{m, -1});
  const int lines = (n - first_line) / 2;  // first_line, first_line + 2, ..., <= n - 2
  const int blocks = (lines + kLinesPerBlock - 1) / kLinesPerBlock;
#pragma omp parallel for schedule(static, 1) if (worth_threads(grid))
  for (int block = 0; block < blocks; ++block) {
    const int begin = first_line + 2 * kLinesPerBlock * block;
    const int end = std::min(n - 1, begin + 2 * kLinesPerBlock);
    for (int j = first; j < n - 1; ++j) {
      for (int i = begin; i < end; i += 2) {
        if (is_held_without_faces(P, f, i, j)) continue;
        RowRange& range = ranges[static_cast<std::size_t>(i)];
        range = {std::min(range.first, j - first), j - first};
      }
    }
  }
  return ranges;
}

LineRelaxation::RowRange LineRelaxation::relax_line(Field& P, const Field& f, int line,
                                                    LineDirection direction, RowRange candidates,
                                                    LineWork& lw) const {
  // The held points at the ends of the line need no system: their changes are
  // zero, so the rows between decouple from them (the same solution to the
  // bit as with them in; on the default case 28 % of the rows).
  const RowRange rows = line_residuals(P, f, line, direction, candidates, lw);
  if (rows.first > rows.last) return rows;
  assemble_line_jacobian(line, direction, rows, lw);
  solve_projected(P, line, direction, rows, lw);
  return rows;
}

LineRelaxation::RowRange LineRelaxation::line_residuals(const Field& P, const Field& f, int line,
                                                        LineDirection direction,
                                                        RowRange candidates, LineWork& lw) const {
  // Point a = first..n-2 of the line is line_point(direction, line, a), row
  // a - first of the line system.
  const int first = op_.grid().first_interior();
  const int m = static_cast<int>(lw.rhs.size());
  lw.coupled_gauss_seidel = 0;
  lw.distributive = 0;
  // Points with P = 0 whose residual would lower the pressure stay at 0 (the
  // projection): held, with no row of their own in the system.  A line of
  // such points only (the cavitated region, a large part of the domain in
  // contact) has nothing to solve.
  RowRange rows{m, -1};
  for (int r = candidates.first; r <= candidates.last; ++r) {
    const auto [i, j] = line_point(direction, line, r + first);
    // A held point of a cavitated neighbourhood needs neither its faces nor
    // its residual (its row is replaced); y_line_candidates asks the same.
    bool held = is_held_without_faces(P, f, i, j);
    if (!held) {
      set_line_row(P, f, i, j, direction, r, lw);
      held = P(i, j) <= 0.0 && lw.rhs[r] >= 0.0;
    }
    lw.fixed_change[r] = held ? 0.0 : std::numeric_limits<double>::quiet_NaN();
    if (held) {
      lw.is_jacobi[r] = 0;
    } else {
      rows = {std::min(rows.first, r), r};
    }
  }
  return rows;
}

void LineRelaxation::set_line_row(const Field& P, const Field& f, int i, int j,
                                  LineDirection direction, int r, LineWork& lw) const {
  // The kernel is symmetric, K(d, 0) = K(0, d), so the band of the elastic
  // term is the same for both directions.
  const bool along_x = direction == LineDirection::X;
  const Grid2D& grid = op_.grid();
  const double h2 = grid.h() * grid.h();
  const bool elastic = op_.elastic();
  const ReynoldsOperator::Faces faces = op_.faces_at(i, j);
  lw.cw[r] = (along_x ? faces.west : faces.south) / h2;
  lw.ce[r] = (along_x ? faces.east : faces.north) / h2;
  lw.cs[r] = (along_x ? faces.south : faces.west) / h2;
  lw.cn[r] = (along_x ? faces.north : faces.east) / h2;
  const double flow = lw.cw[r] + lw.ce[r] + lw.cs[r] + lw.cn[r];
  // Distributive changes also move the four neighbours: next to a cavitated
  // point they would fight the projection, so such points use Gauss-Seidel.
  // Only pressurized points can be distributive or elastically coupled.
  const double elastic_bound =
      elastic && P(i, j) > 0.0 ? settings_.switch_ratio * op_.elastic_diagonal(i, j) : 0.0;
  lw.is_jacobi[r] = elastic && is_pressurized(P, i, j) && flow < elastic_bound;
  const bool flow_dominated = flow >= kFlowDominatedFactor * elastic_bound;
  lw.omega[r] =
      (flow_dominated ? settings_.omega_flow_dominated : settings_.omega_gauss_seidel) * damping_;
  const auto images = static_cast<long>(grid.multiplicity(i) * grid.multiplicity(j));
  if (lw.is_jacobi[r]) {
    lw.distributive += images;
  } else if (P(i, j) > 0.0 && flow < kCoupledGaussSeidelFactor * elastic_bound) {
    lw.coupled_gauss_seidel += images;
  }
  lw.rhs[r] = f(i, j) - op_.apply_at(P, i, j, faces);
}

double LineRelaxation::jacobian_entry(int r, int offset, bool jacobi_unknown,
                                      const RowTransport& transport, double self,
                                      const LineWork& lw) const {
  // d N_r / d (the change of the unknown at `offset` along the line from r).
  // The transport term: tap t lies t meshes upstream (-X) of the row's point,
  // along an X line, across a Y line.
  const bool along_x = transport.direction == LineDirection::X;
  double value = 0.0;
  for (int t = 0; t < kTransportTaps; ++t) {
    if (t > 0 && transport.elastic_scale[t] == 0.0) continue;
    const double k = along_x ? line_kernel(offset + t, 0, jacobi_unknown)
                             : line_kernel(offset, t, jacobi_unknown);
    value += transport.elastic_scale[t] * k;
  }
  if (along_x) {
    // The density of an upstream tap on the line: its own change, or a
    // quarter of a distributive change next to it.
    for (int t = 1; t < kTransportTaps; ++t) {
      if (offset == -t) value += transport.density_scale[t];
      if (jacobi_unknown && std::abs(offset + t) == 1)
        value -= kDistribution * transport.density_scale[t];
    }
  }
  if (!jacobi_unknown) {
    // Change e_c.
    if (offset == 0) value += self;
    if (offset == -1) value += lw.cw[r];
    if (offset == 1) value += lw.ce[r];
    return value;
  }
  // Change e_c - (e_{c-1} + e_{c+1} + e_{c, j-1} + e_{c, j+1}) / 4.
  if (offset == 0)
    value += self - kDistribution * (lw.cs[r] + lw.cn[r]) - kDistribution * (lw.cw[r] + lw.ce[r]);
  if (offset == -1) value += lw.cw[r] - kDistribution * self;
  if (offset == 1) value += lw.ce[r] - kDistribution * self;
  if (offset == -2) value += -kDistribution * lw.cw[r];
  if (offset == 2) value += -kDistribution * lw.ce[r];
  return value;
}

void LineRelaxation::assemble_line_jacobian(int line, LineDirection direction, RowRange rows,
                                            LineWork& lw) const {
  // Row r: the derivatives of N at point p = r + first with respect to the
  // changes of the unknowns within the band.  On a mirrored grid the unknown
  // q stands for the full line's points q and -q, which change alike: the
  // entries of both fold into column q (so the row on the axis couples twice
  // to its neighbour).  Columns outside `rows` are held points, or on a full
  // grid boundary points: not unknowns.
  const Grid2D& grid = op_.grid();
  const int first = grid.first_interior();
  const Field& rho = op_.density();
  const Field& drho = op_.density_derivative();
  const Field& H = op_.film();
  BandMatrix& A = lw.A;
  A.clear_rows(rows.first, rows.last);
  RowTransport transport{direction};
  for (int r = rows.first; r <= rows.last; ++r) {
    // A held row stays cleared: solve_projected replaces it.
    if (!std::isnan(lw.fixed_change[r])) continue;
    const int p = r + first;
    const auto [i, j] = line_point(direction, line, p);
    const TransportTaps taps = op_.taps_at(i);
    for (int t = 0; t < kTransportTaps; ++t) {
      transport.elastic_scale[t] = -taps.weight[t] * rho(i - t, j);
      transport.density_scale[t] = t > 0 ? -taps.weight[t] * drho(i - t, j) * H(i - t, j) : 0.0;
    }
    const double self =
        -(lw.cw[r] + lw.ce[r] + lw.cs[r] + lw.cn[r]) - taps.weight[0] * drho(i, j) * H(i, j);
    for (int c = p - kHalfBand; c <= p + kHalfBand; ++c) {
      const int q = grid.mirrored ? std::abs(c) : c;
      if (q - first < rows.first || q - first > rows.last) continue;
      A(r, q - first) +=
          jacobian_entry(r, c - p, lw.is_jacobi[q - first] != 0, transport, self, lw);
    }
  }
}

void LineRelaxation::solve_projected(const Field& P, int line, LineDirection direction,
                                     RowRange rows, LineWork& lw) const {
  // Projected line solve.  A Gauss-Seidel point whose new pressure would be
  // negative is fixed at P = 0 (its change becomes -P / omega) and the line is
  // solved again, so that its neighbours do not count on a change that the
  // projection would undo; a few passes settle the active set.
  const int first = op_.grid().first_interior();
  const auto begin = static_cast<std::ptrdiff_t>(rows.first);
  const auto end = static_cast<std::ptrdiff_t>(rows.last) + 1;
  std::copy(lw.rhs.begin() + begin, lw.rhs.begin() + end, lw.residual.begin() + begin);
  for (int pass = 0; pass < kMaxActiveSetPasses; ++pass) {
    lw.work.copy_rows(lw.A, rows.first, rows.last);
    std::copy(lw.residual.begin() + begin, lw.residual.begin() + end, lw.rhs.begin() + begin);
    for (int r = rows.first; r <= rows.last; ++r) {
      if (std::isnan(lw.fixed_change[r])) continue;
      const int lo = std::max(rows.first, r - kHalfBand);
      const int hi = std::min(rows.last, r + kHalfBand);
      for (int c = lo; c <= hi; ++c) lw.work(r, c) = 0.0;
      lw.work(r, r) = 1.0;
      lw.rhs[r] = lw.fixed_change[r];
      lw.is_jacobi[r] = 0;
    }
    lw.work.solve(lw.rhs, rows.first, rows.last);
    bool changed = false;
    for (int r = rows.first; r <= rows.last; ++r) {
      if (lw.is_jacobi[r] || !std::isnan(lw.fixed_change[r])) continue;
      const auto [i, j] = line_point(direction, line, r + first);
      const double p = P(i, j);
      if (p + lw.omega[r] * lw.rhs[r] < 0.0) {
        lw.fixed_change[r] = -p / lw.omega[r];
        changed = true;
      }
    }
    if (!changed) break;
  }
}

}  // namespace ehlsim::reynolds
