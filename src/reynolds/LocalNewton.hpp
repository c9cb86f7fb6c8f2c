#pragma once
// Newton's method for N(P) = f on a small window of the finest grid, the
// points outside held: the remedy for errors a few meshes wide that the
// multigrid cycle reduces slowly or not at all (docs/model.md, section 8).
//
// In the collapse of the entrapped pocket before lift-off the largest
// residuals sit at the closing pressure ring, where the flow terms and the
// elastic squeeze term are of one size and xi = rho H^3 / (eta lambda_bar)
// changes by a sixth for a pressure change of 0.01 (alpha_bar = 16.9).  The
// line relaxation freezes xi for a sweep (a Picard step in the flow
// coefficients), and there it overshoots: undamped attempts wander or blow up,
// damped ones converge at 0.7-0.95 per cycle.  The local Newton step
// differentiates the same stencil (ReynoldsOperator::faces_at, taps_at) with
// xi's own dependence on the pressure, through the rheology and through the
// film (the elastic kernel), and solves the window's dense system at once.
#include <functional>
#include <vector>

#include "grid/Grid.hpp"
#include "reynolds/ReynoldsOperator.hpp"

namespace ehlsim::reynolds {

/// A rectangle of interior grid points, bounds inclusive.
struct Window {
  int i0, i1, j0, j1;
  [[nodiscard]] int width() const { return i1 - i0 + 1; }
  [[nodiscard]] int height() const { return j1 - j0 + 1; }
  [[nodiscard]] int size() const { return width() * height(); }
  [[nodiscard]] bool contains(int i, int j) const {
    return i >= i0 && i <= i1 && j >= j0 && j <= j1;
  }
};

/// Up to `count` windows reaching `half_width` meshes to each side of the
/// interior points with the largest pressure-scaled residuals of N(P) = f,
/// largest first and clipped to the interior.  No two overlap, and none is
/// centred where the residual is below kWindowResidualFraction of the largest.
/// Brings the operator's coefficients up to date for P.
[[nodiscard]] std::vector<Window> windows_at_largest_residuals(ReynoldsOperator& op, const Field& P,
                                                               const Field& f, int half_width,
                                                               int count);

/// A window is centred only where the scaled residual is at least this
/// fraction of the largest.  On a stretch of the 1025^2 rebound with up to 30
/// windows, 0.01, 0.05 and 0.2 cost 56.7, 54.7 and 59.4 work units per step
/// (docs/performance.md, "Several windows per cycle").
inline constexpr double kWindowResidualFraction = 0.05;

/// What one local Newton step solved, summed over its windows.
struct LocalNewtonStep {
  int windows = 0;   ///< windows solved
  int unknowns = 0;  ///< their points
  int held = 0;      ///< of them held at P = 0 (cavitated, or projected)
  int undone = 0;    ///< windows whose step raised their largest residual and was undone
};

/// One Newton step on the points of each of `windows` (which must not
/// overlap), all linearised at the same P and solved independently: solves
/// J dP = f - N(P) for the window's pressures (J: the exact derivative of N at
/// P, the points outside held), with points held at P = 0 where the step would
/// make the pressure negative (a few passes settle the active set), and adds
/// dP.  A window whose largest pressure-scaled residual the combined step
/// raises is put back as it was.  Leaves the operator's coefficients up to date
/// for P.  Throws std::runtime_error, with P unchanged, where a window's
/// Jacobian is singular.
LocalNewtonStep local_newton_step(ReynoldsOperator& op, Field& P, const Field& f,
                                  const std::vector<Window>& windows);

/// Where and how wide the windows of a local Newton step are.
struct WindowSearch {
  int half_width;  ///< meshes to each side of a window's centre
  int count;       ///< the most windows
};

/// With solver.local_newton_windows = 0, a local Newton step solves one window
/// per this many points of the side of the grid solved on: 16 on the quadrant
/// of 1025^2, 8 on 513^2, 4 on 257^2.  The errors the cycles leave sit in one
/// ring (the impact's spike foot in the rebound, the closing pocket before
/// lift-off) or line (the rolling contact's outlet spike) whose length in
/// meshes grows with the grid.  Measured per step on the quadrant: 1025^2
/// rebound (T = 3.20-3.26), 93.2 work units with one window, 57.1 with 15,
/// 54.7 with 30; 513^2 whole run 38.4 with one, 34.0 with 8 and 34.2 with 16;
/// 257^2 31.1 with one, 28.0 with 4, 28.5 with 30 (and 25 % more time: most
/// windows were undone) (docs/performance.md).
inline constexpr int kPointsPerLocalNewtonWindow = 32;

/// The windows of a local Newton step on `grid`: `windows` of them (the
/// setting solver.local_newton_windows), or with 0 one per
/// kPointsPerLocalNewtonWindow points of the grid's side.
[[nodiscard]] WindowSearch window_search(int half_width, int windows, const Grid2D& grid);

/// What the mode around a local Newton step does with its global unknown
/// (the impact's Delta, the rolling contact's H0), which every level of its
/// hierarchy shares.
struct GlobalUnknown {
  /// After the step: brings the global unknown in line with the new P and
  /// returns the residual measure of the grid.
  std::function<double()> settle;
  /// Puts the global unknown back to a value it had (the step is taken back).
  std::function<void(double)> restore;
};

/// A local Newton step on the windows at the largest residuals
/// (windows_at_largest_residuals, local_newton_step), kept only when it
/// lowers the grid's residual measure `residual`: each window lowers its own
/// residual, but together, with the global unknown their force implies, they
/// can leave the grid worse (in the collapse of M = 20, L = 20 on 129^2 a
/// step at 9.3e-5 went to 8.7e-4); then P and the global unknown are put
/// back.  Where a window's Jacobian is singular (an iterate that has blown
/// up, say) no step is taken.  Returns the measure after, and leaves the
/// operator's coefficients up to date for P.
double newton_on_worst_windows(ReynoldsOperator& op, Field& P, const Field& f, WindowSearch search,
                               double residual, const GlobalUnknown& global);

}  // namespace ehlsim::reynolds
