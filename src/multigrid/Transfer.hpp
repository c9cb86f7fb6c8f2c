#pragma once
// Grid transfers between a fine grid (n points per side) and the standard
// coarse grid ((n - 1) / 2 + 1 points): vertex-centred, boundary values kept
// on the boundary.  Pure loops over Field views; no knowledge of the physics.
#include "grid/Grid.hpp"

namespace ehlsim::multigrid {

/// coarse(I, J) = fine(2I, 2J).
void inject(const Field& fine, Field& coarse);

/// Full weighting (1/16 [1 2 1; 2 4 2; 1 2 1]) at interior coarse points;
/// boundary coarse points get zero (the residual is zero there).
void restrict_full_weighting(const Field& fine, Field& coarse);

/// Bilinear interpolation of a coarse field, added to `fine` (fine += I coarse).
void prolong_bilinear_add(const Field& coarse, Field& fine);

/// Cubic (4-point Lagrange, per direction) interpolation, overwriting `fine`;
/// used to carry a converged coarse solution up in full multigrid, where a
/// higher order than the discretization keeps the interpolation error small.
void prolong_cubic(const Field& coarse, Field& fine);

}  // namespace ehlsim::multigrid
