#pragma once
// What a running impact simulation reports, step by step, to whoever listens
// (the command's writers and progress line, a test, a study driver).
#include <limits>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "grid/Grid.hpp"

namespace ehlsim {

/// One row of the time series (one time step).
struct StepRecord {
  int step = 0;
  double T = 0.0;
  double Delta = 0.0;
  double dDelta_dT = 0.0;
  double force = 0.0;  ///< Int Int P dX dY
  double h_center = 0.0;
  double h_min = 0.0;
  double p_center = 0.0;
  double p_max = 0.0;
  int cycles = 0;         ///< multigrid cycles used in this step
  double residual = 0.0;  ///< final scaled residual of this step
  int attempts = 1;       ///< 1, plus the retries of the step with more damping
  /// Deformation evaluations of the step, all levels and attempts, in units of
  /// one evaluation on the finest grid (a coarser level's count times its
  /// share of the finest grid's points): the machine-independent cost.
  double work = 0.0;
};

/// One multigrid cycle of a time step (a row of convergence.csv).  Cycle 0 is
/// the start of an attempt: its residual is that of the initial approximation.
struct CycleRecord {
  int step = 0;
  double T = 0.0;        ///< the time the attempt solves for (the end of its interval)
  double dt = 0.0;       ///< the interval: dT, or a half or a quarter of it (halved steps)
  int attempt = 0;       ///< 0, then the retries with more damping
  double damping = 1.0;  ///< the factor on both under-relaxation parameters
  int cycle = 0;
  double residual = 0.0;  ///< the scaled residual after the cycle (solver.tolerance's measure)
};

/// How a run ended with exit 0 (docs/usage.md, "How a run ends"); a run that
/// cannot end honestly throws instead (impact/RunGuards.hpp).
enum class RunOutcome {
  LiftOff,  ///< the film lost its last pressure while the ball moved apart
  AtRest,   ///< the ball stopped in the film: too little energy left for a rebound
  TEnd,     ///< time.T_end reached first
};

inline std::string_view outcome_text(RunOutcome outcome) {
  switch (outcome) {
    case RunOutcome::LiftOff:
      return "lift_off";
    case RunOutcome::AtRest:
      return "at_rest";
    case RunOutcome::TEnd:
      break;
  }
  return "t_end";
}

/// Summary of a finished run.
struct RunSummary {
  int steps = 0;
  RunOutcome outcome = RunOutcome::TEnd;
  bool lifted_off = false;
  double T_final = 0.0;
  double T_lift_off = 0.0;     ///< NaN when the run ended before lift-off
  double rebound_speed = 0.0;  ///< dDelta/dT at lift-off (NaN if no lift-off)
  double max_force = 0.0;
  double T_max_force = 0.0;
  double min_h_center = 0.0;
  double T_min_h_center = 0.0;
  double initial_force = 0.0;  ///< film force at T = 0 (quasi-static squeeze film)
  double impulse = 0.0;        ///< (3 / (2 pi)) Int force dT, from T = 0
  /// The same of the force of the edge band (grid/EdgeBand.hpp): the momentum
  /// [m v0] that the film near the domain's edges took from the ball, where
  /// the boundary condition P = 0 cuts the squeeze film short.
  double edge_impulse = 0.0;
  /// Elastic energy of the solids under the film at T = 0 [m v0^2] (RunGuards.hpp).
  double initial_elastic_energy = 0.0;
  double wall_seconds = 0.0;
  int unconverged_steps = 0;  ///< steps that ended at solver.max_cycles above solver.tolerance
  int retried_steps = 0;      ///< steps solved again with more damping after diverging
  /// Kinetic plus elastic energy left at the end, over the impact energy V0^2 / 2.
  double final_energy = std::numeric_limits<double>::quiet_NaN();
  /// What the user should know about the result, one line each (run_warnings).
  std::vector<std::string> warnings;
};

class ImpactObserver {
 public:
  virtual ~ImpactObserver() = default;
  /// Called once before the first step with the grid the fields live on.
  virtual void on_start(const Grid2D& /*grid*/) {}
  /// Called after every converged time step; `snapshot` says whether this step's
  /// fields are to be stored.
  virtual void on_step(const StepRecord& /*record*/, const Field& /*P*/, const Field& /*H*/,
                       bool /*snapshot*/) {}
  /// Called after every multigrid cycle of a time step, and at the start of
  /// each attempt (cycle 0), before the step's on_step.
  virtual void on_cycle(const CycleRecord& /*record*/) {}
  /// Called after every multigrid cycle of the quasi-static solve at T = 0,
  /// before the first step: `cycle` counts from 1, `residual` is the one
  /// before the cycle (solver.tolerance's measure).
  virtual void on_initial_cycle(int /*cycle*/, double /*residual*/) {}
  virtual void on_finish(const RunSummary& /*summary*/) {}
  /// Asked after every cycle and every completed step: true ends the run with
  /// RunInterrupted after the last completed step (after the state sink has
  /// had that step's state); the step under way is abandoned.
  [[nodiscard]] virtual bool stop_requested() const { return false; }
};

/// Thrown by ImpactProblem::run when the observer asked it to stop: the run
/// ended after the completed step `step` at time `T` (0: before the first
/// step ended, with no state to continue from).
class RunInterrupted : public std::runtime_error {
 public:
  RunInterrupted(int last_step, double last_T)
      : std::runtime_error("the run was asked to stop"), step(last_step), T(last_T) {}
  int step;
  double T;
};

}  // namespace ehlsim
