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
//
// Where three levels dT apart are known, the quadratic extrapolation
// P_last + d1 + d2 (d1 = P_last - P_before, d2 = d1 - (P_before - P_before2))
// starts a step O(dT^3) from its solution.  It is taken at a point only where
// |d2| < |d1|, i.e. where the pressure's history there is resolved in time
// (the terms of the series decrease); where a peak moves across the mesh the
// two are alike, and the point keeps the linear extrapolation.  The same
// bounds apply.  Measured (docs/performance.md, "Quadratic starts and the
// force criterion"): the contact phase takes 1.2 instead of 2.8 cycles per
// step on 257^2 and 513^2.  With one cycle per step the quadratic recurrence
// of the error, e_next = rho (3 e - 3 e_before + e_before2), is neutrally
// stable at a reduction rho = 1/2 per cycle and unstable above (the linear one
// is stable for every rho < 1): the approach converges at about that rate, so
// the quadratic start needs the force criterion of the stopping rule
// (docs/model.md, section 8), which cycles on until such an error is gone.
#include "grid/Grid.hpp"

namespace ehlsim {

/// out = max(0, P_last + omega (P_last - P_before)), bounded point by point
/// as above.  The three fields share one grid; `out` may not alias the
/// others.  Pointwise, so the bits do not depend on the number of threads.
void bounded_extrapolation(const Field& last, const Field& before, double omega, Field& out);

/// out = max(0, the quadratic extrapolation above), of three levels a step
/// apart and for one more step (omega = 1), bounded as the linear one.
void bounded_quadratic_extrapolation(const Field& last, const Field& before, const Field& before2,
                                     Field& out);

}  // namespace ehlsim
