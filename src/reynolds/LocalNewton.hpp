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

/// The window reaching `half_width` meshes to each side of the interior point
/// with the largest pressure-scaled residual of N(P) = f, clipped to the
/// interior.  Brings the operator's coefficients up to date for P.
[[nodiscard]] Window window_at_largest_residual(ReynoldsOperator& op, const Field& P,
                                                const Field& f, int half_width);

/// What one local Newton step solved.
struct LocalNewtonStep {
  int unknowns = 0;      ///< window points
  int held = 0;          ///< of them held at P = 0 (cavitated, or projected)
  bool accepted = true;  ///< false: the step raised the window's largest residual and was undone
};

/// One Newton step on the points of `window`: solves J dP = f - N(P) for the
/// window's pressures (J: the exact derivative of N at P, the points outside
/// held), with points held at P = 0 where the step would make the pressure
/// negative (a few passes settle the active set), and adds dP, unless that
/// raises the window's largest pressure-scaled residual (then P is left as
/// it was).  Leaves the operator's coefficients up to date for P.
LocalNewtonStep local_newton_step(ReynoldsOperator& op, Field& P, const Field& f,
                                  const Window& window);

}  // namespace ehlsim::reynolds
