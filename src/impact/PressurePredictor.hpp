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
// Where three or four levels dT apart are known, the series extrapolation
// P_last + d1 + d2 (+ d3), the backward differences d1 = P_last - P_before,
// d2 = d1 - (P_before - P_before2), d3 = d2 - (the d2 a step earlier), starts
// a step O(dT^3) (O(dT^4)) from its solution.  A term is taken at a point only
// while it is smaller than the one before (|d2| < |d1|, |d3| < |d2|), i.e.
// where the pressure's history there is resolved in time; where a peak moves
// across the mesh the terms are alike, and the point keeps the linear
// extrapolation.  The same bounds apply.  Measured (docs/performance.md,
// "Quadratic starts and the force criterion", "Plain Gauss-Seidel where the
// flow dominates, and cubic starts"): the quadratic
// term took the contact from 2.8 to 1.2 cycles per step on 257^2 and 513^2;
// the cubic one removes the second cycle that the force criterion asked for
// in 34 approach steps of 257^2, where the quadratic start's force was off by
// up to 1.7e-4 of the force (the third difference of the force), and the
// approach takes 1.33 instead of 1.56 cycles per step there.
//
// With one cycle per step the error of a start obeys e_next = rho (2 e -
// e_1), rho (3 e - 3 e_1 + e_2) or rho (4 e - 6 e_1 + 4 e_2 - e_3) (linear,
// quadratic, cubic; rho the reduction of a cycle), neutrally stable at rho =
// 1, 1/2 and 1/5 and unstable above.  The approach's smooth error decays at
// about 0.16 per cycle (0.6 before the flow-dominated points were relaxed
// with solver.omega_flow_dominated = 1): a growing start error is what the
// force criterion of the stopping rule (docs/model.md, section 8) catches, by
// cycling on until it is gone.
#include <cstddef>
#include <span>

#include "grid/Grid.hpp"

namespace ehlsim {

/// out = max(0, P_last + omega (P_last - P_before)), bounded point by point
/// as above.  The three fields share one grid; `out` may not alias the
/// others.  Pointwise, so the bits do not depend on the number of threads.
void bounded_extrapolation(const Field& last, const Field& before, double omega, Field& out);

/// The most levels before the last one that bounded_series_extrapolation uses.
inline constexpr std::size_t kMaxEarlierLevels = 3;

/// out = max(0, the series extrapolation above) for one more step (omega =
/// 1), of `last` and the 1 to kMaxEarlierLevels levels before it, a step apart
/// (earlier[0] the one before `last`), bounded as the linear one.
void bounded_series_extrapolation(const Field& last, std::span<const Field* const> earlier,
                                  Field& out);

}  // namespace ehlsim
