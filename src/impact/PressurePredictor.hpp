#pragma once
// The initial approximation of a time step's pressure from the last two time
// levels (ImpactProblem::Impl::choose_start).
//
// Linear extrapolation in time, P_last + omega (P_last - P_before), starts a
// step O(dT^2) from its solution where the pressure is smooth.  It does not
// where a narrow peak moves across the mesh: the spike of the rebound moves by
// about one mesh per step on every grid (dT = h), and extrapolating it point by
// point doubles its height at the new position and digs a hole at the old one.
// On a 1025^2 checkpoint at T = 3.5 the extrapolated start had a largest
// pressure of 4.97 against 2.75 in the solution; the first cycles of each step
// went into undoing it, and the undamped first attempts often blew up.
//
// So the extrapolated value of each point is bounded by the range of P_last
// over the point and its eight neighbours, widened by omega times the smallest
// change in time among those nine points.  A peak that moves has a neighbour
// that hardly changed, so its extrapolation is held within the peak's own
// height; a pressure that changes alike over a neighbourhood (the approach,
// the growing Hertzian dome) keeps the full extrapolation, and with it second
// order.  Where P is smooth, the bound takes nothing away from a point whose
// change per step is below P's change to its neighbours, and at a smooth
// maximum or minimum at most omega times the spread of the nine changes.
#include "grid/Grid.hpp"

namespace ehlsim {

/// out = max(0, P_last + omega (P_last - P_before)), bounded point by point
/// as above.  The three fields share one grid; `out` may not alias the
/// others.  Pointwise, so the bits do not depend on the number of threads.
void bounded_extrapolation(const Field& last, const Field& before, double omega, Field& out);

}  // namespace ehlsim
