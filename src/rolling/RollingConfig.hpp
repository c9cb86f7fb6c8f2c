#pragma once
// Everything that defines one steady rolling point-contact run (model.md,
// "Steady rolling point contact"), in the Hertz units of the contact: X, Y in
// a = (3 w Rx / (2 E'))^(1/3), P in ph = 3 w / (2 pi a^2), H = h Rx / a^2.
// For an elliptic contact (D = Rx / Ry != 1) a and ph are those of a ball of
// radius Rx under the same load: the deformation stays (2/pi^2) Int P / r, the
// force balance Int P = 2 pi / 3, and only the undeformed gap changes, to
// X^2/2 + D Y^2/2 (docs/model.md).
//
// Values only: defaults, ranges and docs live once, in config/RollingParameters.
#include <optional>

#include "reynolds/SolverSettings.hpp"
#include "rheology/Lubricant.hpp"

namespace ehlsim {

/// Physical inputs (SI) of a rolling contact and what follows from them.
struct RollingPhysical {
  double Rx_m = 0.0, Ry_m = 0.0;      ///< reduced radii of curvature along and across the rolling
  double load_N = 0.0;                ///< w
  double u1_m_s = 0.0, u2_m_s = 0.0;  ///< surface speeds
  double reduced_modulus_Pa = 0.0;    ///< E'
  double eta0_Pa_s = 0.0;
  double alpha_per_Pa = 0.0;
  // derived
  double a_m = 0.0;         ///< Hertz radius of the reference ball contact
  double ph_Pa = 0.0;       ///< its maximum pressure
  double U = 0.0, W = 0.0;  ///< Moes speed and load groups
};

struct RollingConfig : SolverSettings {
  // [case]
  double M = 100.0;
  double L = 10.0;
  double D = 1.0;           ///< Rx / Ry
  double lambda_bar = 0.0;  ///< from M
  double alpha_bar = 0.0;   ///< from M and L
  std::optional<RollingPhysical> physical;
  // [lubricant]
  Lubricant lubricant;
  // [body]
  bool elastic = true;
  // [grid]
  int grid_points = 257;
  double x_min = -4.5, x_max = 1.5, y_min = -3.0, y_max = 3.0;
  // [solver] (the rest is SolverSettings)
  /// Fraction of the Newton change of H0 applied after each cycle.  1: the
  /// force error then falls as fast as the residual (0.5 halved it per
  /// cycle and doubled the cycles; M = 10, L = 0 on 129^2).
  double h0_relaxation = 1.0;
  /// Cycles on each coarse level of the full multigrid start.  8: with 4,
  /// L = 20 on 1025^2 ended with exit 1 for M = 10, 20, 50 and 100 (the
  /// damped retries of the finest grid stalled at the outlet spike from a
  /// start carried up less converged: M = 50's 513^2 stage ended at 1.8e-2,
  /// with 8 at 6.8e-3); with 8 M = 20, 50 and 100 converge in 76, 140 and
  /// 167 cycles, and the chart on 257^2 and 513^2 takes 336 and 526 cycles
  /// instead of 364 and 538, for 1 % and 3 % more work (docs/validation.md,
  /// "L = 20 on 1025^2").
  int fmg_cycles = 8;
  /// An elastic run that runs out of cycles with the deformation update of
  /// solver.deformation_updates solves again from its start with the other
  /// one.  At L = 20 on 1025^2 each converges a case the other does not: M =
  /// 10 ran out of 200 cycles (residual 0.28) once per sweep and converged in
  /// 224 before each colour; M = 20 converged in 76 once per sweep and ran out
  /// of 400 before each colour (docs/validation.md, "M = 10, L = 20").
  bool fallback_update = true;
  /// tolerance 1e-5: with the local Newton step after each finest-grid cycle
  /// (SolverSettings::local_newton_half_width), whose windows clear the
  /// residual of the outlet spike before the smooth error has gone, 1e-4 left
  /// Hc 1.6e-3 from its converged value at M = 1000, L = 10 on 513^2 (5
  /// cycles); 1e-5 leaves 6e-5 (9 cycles), and 1.6e-5 on the default case
  /// (257^2, 8 cycles; 9 at 1e-4 without the windows), some 300 times below
  /// the discretisation error (Hc moves 0.7 % from 257^2 to 513^2).  A rigid
  /// Barus contact near its bound on alpha_bar balances its force at 0.96
  /// per cycle (M = 10, L = 0.4 on 129^2: force error 1e-4 after 100 cycles,
  /// converged in 121).  max_cycles bounds the finest-grid cycles of all
  /// attempts: at L = 20 the damped retries converge at 0.85-0.95 per cycle
  /// (the outlet spike), and the cycles move by tens with the last bits of a
  /// run (M = 20 on 513^2: 41 and 80 cycles at two revisions of the same
  /// solver, 100 with a trial form of the H0 step's regrowth; M = 10: 69,
  /// more than 100, 79).  300, not 200: M = 10, L = 20 on 1025^2 converges
  /// only with the per-colour update, and there its residual wanders between
  /// 5e-6 and 1e-4 from about cycle 150 on: below the tolerance, force error
  /// with it, at cycle 224 and at 283 in two runs (docs/validation.md, "M =
  /// 10, L = 20").  Each of the two runs of fallback_update has max_cycles; a
  /// case that converges with neither fails after about 0.7 s per cycle on
  /// 1025^2, two threads.
  /// V(2,1) with switch_ratio 0.3 (Venner & Lubrecht's value; the impact
  /// needs 3, LineRelaxation.hpp): the least work of the four combinations with
  /// V(3,2) and 3, 2026-11-30 on 257^2 (`ehlsim rolling --set
  /// solver.pre_sweeps=A --set solver.post_sweeps=B --set
  /// solver.switch_ratio=S`): the default case 68 work units (8 cycles)
  /// against 106, 112 and 153; M = 20, L = 20 250 against 424, 319 and 732;
  /// Hc the same to 1e-5.
  RollingConfig() {
    tolerance = 1e-5;
    max_cycles = 300;
    pre_sweeps = 2;
    post_sweeps = 1;
    coarsest_points = 17;
    relaxation.switch_ratio = 0.3;
    // The impact's plain Gauss-Seidel at flow-dominated points left M = 50,
    // L = 20 on 513^2 unconverged after 100 cycles (residual 9.9e-4, the
    // test Rolling.CentralFilmConvergesAtL20AfterADivergedFirstAttempt).
    relaxation.omega_flow_dominated = relaxation.omega_gauss_seidel;
  }
};

}  // namespace ehlsim
