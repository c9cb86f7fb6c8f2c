#include "reynolds/LocalNewton.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <tuple>
#include <vector>

#include "reynolds/DenseSolve.hpp"

namespace ehlsim::reynolds {

namespace {
/// Passes of the projected solve, as in the line relaxation: the active set
/// of a window settles in one or two.
constexpr int kMaxActiveSetPasses = 4;

/// The residual of N(P) = f at an interior point, as the FAS level counts it.
double point_residual(const ReynoldsOperator& op, const Field& P, const Field& f, int i, int j) {
  return constrained_residual(P(i, j), f(i, j) - op.apply_at(P, i, j));
}

/// |point_residual| / |dN/dP| of a point.
double scaled_point_residual(const ReynoldsOperator& op, const Field& P, const Field& f, int i,
                             int j) {
  return std::abs(op.pressure_scaled(point_residual(op, P, f, i, j), i, j));
}

/// The window's unknowns, numbered row by row; on a mirrored grid an index
/// across an axis is its mirror image.
struct WindowIndex {
  const Window& window;
  bool mirrored;
  /// The unknown of point (i, j), or -1 outside the window.
  [[nodiscard]] int operator()(int i, int j) const {
    if (mirrored) i = std::abs(i), j = std::abs(j);
    if (!window.contains(i, j)) return -1;
    return (j - window.j0) * window.width() + (i - window.i0);
  }
};

/// dH(a, b) / dP(q) for every unknown q of a window, for the films its rows
/// hold: the window's points, their four neighbours and the transport taps
/// upstream.  Each film enters up to seven rows, so the kernel sums of
/// ReynoldsOperator::film_slope are taken once per film, not once per row
/// (the same values, so the same Jacobian to the bit).
class FilmSlopes {
 public:
  FilmSlopes(const ReynoldsOperator& op, const WindowIndex& index)
      : op_(op),
        index_(index),
        i0_(index.window.i0 - (kTransportTaps - 1)),
        j0_(index.window.j0 - 1),
        width_(index.window.width() + kTransportTaps),
        height_(index.window.height() + 2),
        unknowns_(index.window.size()),
        known_(static_cast<std::size_t>(width_) * height_, 0) {
    slopes_.resize(known_.size() * static_cast<std::size_t>(unknowns_));
  }

  /// dH(a, b) / dP(q) for the unknowns q in window order.
  [[nodiscard]] const double* of(int a, int b) {
    const auto cell = static_cast<std::size_t>((b - j0_) * width_ + (a - i0_));
    double* row = slopes_.data() + cell * static_cast<std::size_t>(unknowns_);
    if (known_[cell]) return row;
    const Window& w = index_.window;
    for (int l = w.j0; l <= w.j1; ++l)
      for (int k = w.i0; k <= w.i1; ++k) row[index_(k, l)] = op_.film_slope(a, b, k, l);
    known_[cell] = 1;
    return row;
  }

 private:
  const ReynoldsOperator& op_;
  const WindowIndex& index_;
  int i0_, j0_, width_, height_, unknowns_;
  std::vector<char> known_;
  std::vector<double> slopes_;
};

/// A point whose film enters a row of N, and the row's derivative with
/// respect to that film.
struct FilmTerm {
  int i, j;
  double weight;
};
/// The most films a row holds: the point, its four neighbours and the
/// transport stencil's taps upstream of the point.
constexpr int kMaxFilmTerms = 1 + 4 + (kTransportTaps - 1);

/// One row of the Jacobian (column-major matrix `J` of the window's size):
/// d N(i, j) / d P(q) for every unknown q.  N holds P directly through the
/// flow stencil, and the films of the point, its four neighbours (through xi
/// on the faces) and its transport taps, each of which follows every pressure
/// through the elastic kernel.
void add_jacobian_row(const ReynoldsOperator& op, const Field& P, const WindowIndex& index,
                      FilmSlopes& film_slopes, int i, int j, std::vector<double>& J) {
  const int m = index.window.size();
  const int row = index(i, j);
  const auto entry = [&](int q) -> double& { return J[static_cast<std::size_t>(q) * m + row]; };
  const double h2 = op.grid().h() * op.grid().h();
  const Field& xi = op.xi();
  const Field& H = op.film();
  const ReynoldsOperator::Faces faces = op.faces_at(i, j);
  const std::array<std::array<int, 2>, 4> neighbour{
      {{i - 1, j}, {i + 1, j}, {i, j - 1}, {i, j + 1}}};
  const std::array<double, 4> face{faces.west, faces.east, faces.south, faces.north};
  std::array<FilmTerm, kMaxFilmTerms> films{};
  int film_count = 0;
  const auto add_film = [&](int a, int b, double weight) {
    for (int k = 0; k < film_count; ++k) {
      if (films[k].i == a && films[k].j == b) {
        films[k].weight += weight;
        return;
      }
    }
    films[film_count++] = {a, b, weight};
  };
  const double xi_p = xi(i, j);
  // d xi / d H = 3 xi / H where the film is open (xi uses max(H, 0)).
  const double xi_film_p = H(i, j) > 0.0 ? 3.0 * xi_p / H(i, j) : 0.0;
  for (int k = 0; k < 4; ++k) {
    const auto [a, b] = neighbour[k];
    entry(row) -= face[k] / h2;
    if (const int q = index(a, b); q >= 0) entry(q) += face[k] / h2;
    // The face coefficient follows xi at both of its ends.
    const double gradient = (P(a, b) - P(i, j)) / h2;
    const FaceSlopes slope = face_coefficient_slopes(xi_p, xi(a, b), op.face_mean());
    entry(row) += gradient * slope.a * xi_p * op.flow_factor_log_slope(P(i, j));
    if (const int q = index(a, b); q >= 0)
      entry(q) += gradient * slope.b * xi(a, b) * op.flow_factor_log_slope(P(a, b));
    const double xi_film_n = H(a, b) > 0.0 ? 3.0 * xi(a, b) / H(a, b) : 0.0;
    add_film(i, j, gradient * slope.a * xi_film_p);
    add_film(a, b, gradient * slope.b * xi_film_n);
  }
  // The transport term -sum_t w_t (rho H)(i - t, j): its density and its film.
  const TransportTaps taps = op.taps_at(i);
  for (int t = 0; t < kTransportTaps; ++t) {
    if (taps.weight[t] == 0.0) continue;
    if (const int q = index(i - t, j); q >= 0)
      entry(q) -= taps.weight[t] * op.density_derivative()(i - t, j) * H(i - t, j);
    add_film(i - t, j, -taps.weight[t] * op.density()(i - t, j));
  }
  if (!op.elastic()) return;
  std::array<const double*, kMaxFilmTerms> slopes{};
  for (int t = 0; t < film_count; ++t) slopes[t] = film_slopes.of(films[t].i, films[t].j);
  for (int q = 0; q < m; ++q) {
    double sum = 0.0;
    for (int t = 0; t < film_count; ++t) sum += films[t].weight * slopes[t][q];
    entry(q) += sum;
  }
}

/// Solves J dP = r with the held rows (held[q] finite: dP(q) = held[q])
/// replaced by identity rows, holding at P = 0 every free point the step
/// would make negative, until the active set settles.
std::vector<double> solve_projected(const std::vector<double>& J, const std::vector<double>& r,
                                    std::vector<double>& held, const std::vector<double>& p) {
  const int m = static_cast<int>(r.size());
  std::vector<double> A, x;
  for (int pass = 0; pass < kMaxActiveSetPasses; ++pass) {
    A = J;
    x = r;
    for (int q = 0; q < m; ++q) {
      if (std::isnan(held[q])) continue;
      for (int c = 0; c < m; ++c) A[static_cast<std::size_t>(c) * m + q] = 0.0;
      A[static_cast<std::size_t>(q) * m + q] = 1.0;
      x[q] = held[q];
    }
    if (!solve_dense(A, x, m))
      throw std::runtime_error("local Newton step: the window's Jacobian is singular");
    bool settled = true;
    for (int q = 0; q < m; ++q) {
      if (std::isnan(held[q]) && p[q] + x[q] < 0.0) {
        held[q] = -p[q];
        settled = false;
      }
    }
    if (settled) break;
  }
  return x;
}
}  // namespace

namespace {
/// The largest pressure-scaled residual of the window's points.
double largest_scaled_residual(const ReynoldsOperator& op, const Field& P, const Field& f,
                               const Window& window) {
  double largest = 0.0;
  for (int j = window.j0; j <= window.j1; ++j)
    for (int i = window.i0; i <= window.i1; ++i)
      largest = std::max(largest, scaled_point_residual(op, P, f, i, j));
  return largest;
}

/// The pressure-scaled residual |r| / diagonal at every interior point, 0 on
/// the boundary.
Field scaled_residuals(const ReynoldsOperator& op, const Field& P, const Field& f) {
  const Grid2D& grid = op.grid();
  const int first = grid.first_interior();
  Field scaled(grid);
#pragma omp parallel for schedule(static) if (worth_threads(grid))
  for (int j = first; j < grid.n - 1; ++j)
    for (int i = first; i < grid.n - 1; ++i) scaled(i, j) = scaled_point_residual(op, P, f, i, j);
  return scaled;
}

/// A window's Newton step, solved at the P it was linearised at.
struct WindowSolve {
  std::vector<double> start;      ///< the window's pressures before the step
  std::vector<double> change;     ///< dP
  int held = 0;                   ///< unknowns held at P = 0
  double largest_residual = 0.0;  ///< before the step
};

WindowSolve solve_window(const ReynoldsOperator& op, const Field& P, const Field& f,
                         const Window& window) {
  const WindowIndex index{window, op.grid().mirrored};
  const int m = window.size();
  std::vector<double> J(static_cast<std::size_t>(m) * m, 0.0), r(m);
  WindowSolve solve{std::vector<double>(m), {}, 0, largest_scaled_residual(op, P, f, window)};
  // held: NaN for a free unknown, else the change it is held to.
  std::vector<double> held(m, std::numeric_limits<double>::quiet_NaN());
  FilmSlopes film_slopes(op, index);
  for (int j = window.j0; j <= window.j1; ++j) {
    for (int i = window.i0; i <= window.i1; ++i) {
      const int q = index(i, j);
      solve.start[q] = P(i, j);
      r[q] = f(i, j) - op.apply_at(P, i, j);
      // A cavitated point whose residual would lower the pressure stays at 0.
      if (P(i, j) <= 0.0 && r[q] >= 0.0) held[q] = 0.0;
      add_jacobian_row(op, P, index, film_slopes, i, j, J);
    }
  }
  solve.change = solve_projected(J, r, held, solve.start);
  solve.held = static_cast<int>(
      std::count_if(held.begin(), held.end(), [](double v) { return !std::isnan(v); }));
  return solve;
}

/// Writes start + change (at least 0) into the window's points of P.
void put_window(const Window& window, bool mirrored, const std::vector<double>& start,
                const std::vector<double>* change, Field& P) {
  const WindowIndex index{window, mirrored};
  for (int j = window.j0; j <= window.j1; ++j) {
    for (int i = window.i0; i <= window.i1; ++i) {
      const int q = index(i, j);
      P(i, j) = change ? std::max(0.0, start[q] + (*change)[q]) : start[q];
    }
  }
}

/// Whether the windows of half-width w centred at a and b share a point.
bool overlap(std::array<int, 2> a, std::array<int, 2> b, int w) {
  return std::abs(a[0] - b[0]) <= 2 * w && std::abs(a[1] - b[1]) <= 2 * w;
}
}  // namespace

std::vector<Window> windows_at_largest_residuals(ReynoldsOperator& op, const Field& P,
                                                 const Field& f, int half_width, int count) {
  op.update_coefficients(P);
  const Grid2D& grid = op.grid();
  const int first = grid.first_interior();
  const Field scaled = scaled_residuals(op, P, f);
  const double floor =
      kWindowResidualFraction * *std::max_element(scaled.span().begin(), scaled.span().end());
  // (-residual, j, i): largest first, ties in grid order, the same on every run.
  std::vector<std::tuple<double, int, int>> candidates;
  for (int j = first; j < grid.n - 1; ++j)
    for (int i = first; i < grid.n - 1; ++i)
      if (scaled(i, j) >= floor) candidates.emplace_back(-scaled(i, j), j, i);
  std::sort(candidates.begin(), candidates.end());
  std::vector<std::array<int, 2>> centres;
  std::vector<Window> windows;
  for (const auto& [residual, jc, ic] : candidates) {
    if (static_cast<int>(windows.size()) >= count) break;
    const std::array<int, 2> centre{ic, jc};
    if (std::any_of(centres.begin(), centres.end(),
                    [&](const auto& c) { return overlap(c, centre, half_width); }))
      continue;
    centres.push_back(centre);
    const auto [i, j] = centre;
    windows.push_back({std::max(first, i - half_width), std::min(grid.n - 2, i + half_width),
                       std::max(first, j - half_width), std::min(grid.n - 2, j + half_width)});
  }
  return windows;
}

LocalNewtonStep local_newton_step(ReynoldsOperator& op, Field& P, const Field& f,
                                  const std::vector<Window>& windows) {
  op.update_coefficients(P);
  const int count = static_cast<int>(windows.size());
  std::vector<WindowSolve> solves(count);
  bool singular = false;
  // Each window's system is independent of the others' (all at the same P).
#pragma omp parallel for schedule(dynamic, 1) if (count > 1)
  for (int w = 0; w < count; ++w) {
    try {
      solves[w] = solve_window(op, P, f, windows[w]);
    } catch (const std::exception&) {  // no exception may leave a parallel region
#pragma omp atomic write
      singular = true;
    }
  }
  if (singular) throw std::runtime_error("local Newton step: a window's Jacobian is singular");
  const bool mirrored = op.grid().mirrored;
  LocalNewtonStep step;
  for (int w = 0; w < count; ++w) {
    put_window(windows[w], mirrored, solves[w].start, &solves[w].change, P);
    step.unknowns += windows[w].size();
    step.held += solves[w].held;
  }
  step.windows = count;
  op.update_coefficients(P);
  // Far from the solution (a rough iterate, a coefficient that jumps by
  // orders between neighbours) the linearisation can overshoot: a window
  // left worse than it was is put back.
  for (int w = 0; w < count; ++w) {
    if (largest_scaled_residual(op, P, f, windows[w]) > solves[w].largest_residual) {
      put_window(windows[w], mirrored, solves[w].start, nullptr, P);
      ++step.undone;
    }
  }
  if (step.undone > 0) op.update_coefficients(P);
  return step;
}

WindowSearch window_search(int half_width, int windows, const Grid2D& grid) {
  if (windows > 0) return {half_width, windows};
  return {half_width, std::max(1, grid.n / kPointsPerLocalNewtonWindow)};
}

double newton_on_worst_windows(ReynoldsOperator& op, Field& P, const Field& f, WindowSearch search,
                               double residual, const GlobalUnknown& global) {
  const Field P_start = P;
  const double delta_start = op.delta();
  const std::vector<Window> windows =
      windows_at_largest_residuals(op, P, f, search.half_width, search.count);
  try {
    local_newton_step(op, P, f, windows);
  } catch (const std::runtime_error&) {
    // A singular window (an iterate that has blown up; no flow and no
    // elastic term around a point) leaves P as it was: no step.  The caller
    // records its cycle with the residual it had, and judges it.
    return residual;
  }
  const double after = global.settle();
  if (after <= residual) return after;
  P = P_start;
  global.restore(delta_start);
  // settle() brought the coefficients to the P taken back; the film and the
  // rheology the caller reads next (the rolling contact's Hc) are P's again.
  op.update_coefficients(P);
  return residual;
}

}  // namespace ehlsim::reynolds
