#pragma once
// Everything that defines one lubricated-impact run, in dimensionless form
// (plus the physical inputs when the case was given in physical units).
//
// This struct carries values only: defaults, ranges and documentation of every
// key live once, in the parameter registry (config/Parameters).
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "analysis/SpikeSettings.hpp"
#include "reynolds/FaceMean.hpp"
#include "reynolds/LineRelaxation.hpp"
#include "reynolds/SolverSettings.hpp"
#include "rheology/Lubricant.hpp"
#include "rheology/Models.hpp"

namespace ehlsim {

/// Physical inputs (SI units) and the reference scales derived from them (model.md).
struct PhysicalCase {
  // inputs
  double reduced_radius_m = 0.0;    ///< R
  double mass_kg = 0.0;             ///< m
  double impact_speed_m_s = 0.0;    ///< v0
  double reduced_modulus_Pa = 0.0;  ///< E'
  double eta0_Pa_s = 0.0;           ///< ambient viscosity
  double alpha_per_Pa = 0.0;        ///< pressure-viscosity coefficient
  double rho0_kg_m3 = 0.0;          ///< ambient density
  // derived scales
  double delta_star_m = 0.0;
  double a_star_m = 0.0;
  double ph_star_Pa = 0.0;
  double F_star_N = 0.0;
  double t_bar_s = 0.0;
};

/// The start in the contracting frame (impact/PressurePredictor.hpp) is
/// offered when the better of the other two starts of a step leaves a residual
/// above this many times solver.tolerance: in the rebound and the collapse
/// (0.04-0.2 at 257^2 and 513^2), not in the contact (1e-4 and below), where
/// it was the better start in 6 of 57 steps above 10 times the tolerance on
/// 257^2 and cost a residual evaluation in each (docs/performance.md, "Starts
/// in a contracting frame").
inline constexpr double kContractingStartTrigger = 100.0;

/// The multigrid settings (SolverSettings, shared with the other modes) are
/// its base: cfg.tolerance, cfg.relaxation, ...  Their impact defaults are
/// SolverSettings' own: max_cycles 20 per attempt of a time step, because the
/// hardest steps of the spike phase converge at 0.5-0.7 per cycle from a start
/// residual ~1e-1 (257^2).
struct ImpactConfig : SolverSettings {
  [[nodiscard]] const SolverSettings& solver_settings() const { return *this; }

  // [case] Moes parameters and the dimensionless groups they fix.
  double M = 100.0;
  double L = 10.0;
  double lambda_bar = 0.0;               ///< derived from M unless given
  double alpha_bar = 0.0;                ///< derived from M, L unless given
  std::optional<PhysicalCase> physical;  ///< set when a [physical] section was given

  // [lubricant]: the laws and their inputs; the solver's alpha_bar is the
  // case's (Lubricant::with_alpha_bar).
  Lubricant lubricant;

  // [body]
  bool elastic = true;

  // [grid]
  int grid_points = 257;
  double half_width = 1.5;

  // [time]
  double dT = 0.0;                                         ///< 0: equal to the mesh size
  double T_end = std::numeric_limits<double>::infinity();  ///< inf: until lift-off
  /// Cap on the steps of a run until lift-off; 0: default_max_steps (impact/RunGuards.hpp).
  int max_steps = 0;
  double Delta0 = 1.0;
  double V0 = 1.0;

  // [surface]
  double waviness_amplitude = 0.0;
  double waviness_wavelength = 1.0;
  double waviness_angle_deg = 0.0;

  // [solver]: the settings every mode has are the base SolverSettings;
  // these belong to the time stepping.
  /// In the retries of a step: undo a coarse-grid correction that raises its
  /// level's residual norm more than this many times (multigrid/Fas.hpp); 0:
  /// never.  10: a good correction lowers the norm 5-7 times, the largest rise
  /// seen in converging 129^2 steps was 4.3.
  double correction_safeguard = 10.0;
  /// The first retry of a step scales the under-relaxation by this, each
  /// further retry by half as much again (ImpactProblem.cpp, attempt_damping).
  double retry_damping = 0.8;
  /// A step has converged when, besides the residual measure, its last cycle
  /// changed the film force by less than this times the largest force so far
  /// (docs/model.md, section 8); 0: the residual measure alone.  The measure
  /// hardly sees a smooth error: a first step whose force was 7 % off passed
  /// it on 257^2.  1e-4: the rebound speed and the maximum force of 129^2 and
  /// 257^2 within 1.2e-5 of runs converged to 1e-8, against 1.2e-4 and 4.1e-4
  /// (129^2) with the measure alone (docs/performance.md).
  double force_tolerance = 1e-4;
  /// Where the other starts of a step are poor (kContractingStartTrigger),
  /// also try the one extrapolated in a frame that contracts with the pressure
  /// (impact/PressurePredictor.hpp).
  bool contracting_start = true;
  /// Solve on the quadrant X, Y >= 0 when the case is even in X and Y
  /// (solver.symmetry = auto); false: always the full domain.
  bool use_symmetry = true;

  // [output]
  /// 20: the spacing of the pressure profiles of the paper's figure 3 ("time
  /// increments of 20 time steps"; Lubrecht & Venner 2022, section 4).
  int snapshot_every = 20;
  std::vector<double> snapshot_times;
  double snapshot_start = 0.0;  ///< the periodic snapshots begin at this time
  int checkpoint_every = 0;     ///< steps between checkpoints (0: none)

  // [spike] the pressure-spike analysis (spike.csv, `ehlsim spike`)
  SpikeSettings spike;
};

/// The time step the run uses: time.dT, or the mesh size when dT == 0
/// (defined with the problem, ImpactProblem.cpp).
[[nodiscard]] double effective_time_step(const ImpactConfig& config);

}  // namespace ehlsim
