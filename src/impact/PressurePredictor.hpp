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

// The start in a contracting frame.  In the rebound the spike ring runs
// inward with the receding contact, about 0.6 of a mesh per step on every grid
// (dT = h), and the whole pressure field shrinks towards the axis of the ball.
// Seen point by point that history is not resolved in time, and the starts
// above leave the spike's error: a residual measure of 0.04-0.2 at the start
// of a rebound step against 1e-4 in the contact (257^2 and 513^2), 46-93 % of
// its square within four meshes of the spike.  In a frame that shrinks
// with the field the spike stands still: each level k steps back is seen at
// contraction^(k+1), i.e. Q_k(X, Y) = P_k(c^(k+1) X, c^(k+1) Y), and the
// series extrapolation of the Q_k (bounded as above) is the start.  c comes
// from the last two levels (radial_contraction); the series carries the
// change of the spike's height, which the frame leaves.  The interpolation
// smears a spike one mesh wide, so the start is the better one only where the
// others are poor: ImpactProblem offers it when their residual is far above the
// tolerance, and keeps it only if its residual is smaller (docs/performance.md,
// "Starts in a contracting frame").

/// out(X, Y) = field(c X, c Y), by bilinear interpolation, about the origin of
/// the coordinates (the ball's axis); zero where (c X, c Y) lies beyond the
/// grid, and on the grid's outer boundary, where the pressure is held at zero.
void contract_radially(const Grid2D& grid, const Field& field, double contraction, Field& out);

/// The bounds of radial_contraction: a step shrinks the pressure field to at
/// least 0.8 of its size or grows it to at most 1.25 times.  The spike radius
/// of the rebound (R_s of spike.csv, to T = 3.9) shrinks by at most 1.17 per
/// step on 65^2, the coarsest grid of the case maps, and 1.04 on 257^2; where
/// it shrinks faster (the collapse of the pocket), the search ends at the
/// bound and the residual decides whether the start is taken.
inline constexpr double kMinContraction = 0.8;
inline constexpr double kMaxContraction = 1.25;
/// The golden-section search ends when the contraction is known to this: at
/// R = 0.7 a displacement of 2.4 % of a 1025^2 mesh.
inline constexpr double kContractionResolution = 1e-4;

/// The c in [kMinContraction, kMaxContraction] for which `before` contracted
/// by c (contract_radially), times the amplitude that fits best, is nearest
/// `last` in the least-squares sense (the rebound's spike grows as it runs
/// inward: a misfit without the amplitude would trade size for height), by a
/// golden-section search over the square about the origin that holds both
/// pressures.  The same bits on any number of threads.
[[nodiscard]] double radial_contraction(const Grid2D& grid, const Field& last, const Field& before);

/// The start in the contracting frame: out = the bounded series
/// extrapolation of `last` and the 1 to kMaxEarlierLevels levels before it, a
/// step apart, each seen in the frame of the next step: contracted by c for
/// `last` and by c^(k+1) for the level k steps before it, c = `contraction`
/// (radial_contraction of `last` and the level before it).
void contracting_frame_extrapolation(const Grid2D& grid, const Field& last,
                                     std::span<const Field* const> earlier, double contraction,
                                     Field& out);

}  // namespace ehlsim
