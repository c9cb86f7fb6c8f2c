#include "impact/ImpactProblem.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstddef>
#include <limits>
#include <numbers>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "dynamics/Bdf.hpp"
#include "dynamics/Newmark.hpp"
#include "grid/EdgeBand.hpp"
#include "grid/FieldExtrema.hpp"
#include "grid/NumberText.hpp"
#include "impact/AttemptPolicy.hpp"
#include "impact/PressurePredictor.hpp"
#include "impact/RunGuards.hpp"
#include "multigrid/Fas.hpp"
#include "reynolds/LocalNewton.hpp"
#include "reynolds/ReynoldsHierarchy.hpp"

namespace ehlsim {

bool is_mirror_symmetric(const ImpactConfig& c) {
  if (!c.use_symmetry) return false;
  if (c.waviness_amplitude == 0.0) return true;
  const double quarter_turns = c.waviness_angle_deg / 90.0;
  return quarter_turns == std::round(quarter_turns);
}

double effective_time_step(const ImpactConfig& config) {
  if (config.dT > 0.0) return config.dT;
  return Grid2D(config.grid_points, config.half_width).h();
}

namespace {
/// A step whose residual grows this far above its starting value has diverged.
constexpr double kDivergenceFactor = 1e3;
/// Each retry after the first halves the damping factor once more.
constexpr double kFurtherRetryDamping = 0.5;
/// A run to time.T_end ends with the step whose T is within this fraction of
/// a step of it: T is a sum of steps (and halves of steps) in floating point,
/// which can fall short of a T_end it should reach by a few roundings.
constexpr double kEndTimeSlack = 1e-9;
/// The attempt from which on a step brings the deformation up to date before
/// each colour of a sweep (once per sweep before it: section 7 of
/// docs/model.md): the second retry on.  The last retry only cost less on the
/// 1025^2 default case (105 against 140 work units per step in the rebound,
/// 205 against 283 in the pocket collapse), but the paper's study on 1025^2
/// then failed M = 20 at T = 3.9375 and M = 10 at T = 3.6885 (exit 1, no
/// attempt converged), which the second retry on had solved; never before
/// each colour, M = 20, L = 20 on 129^2 fails at T = 3.773
/// (docs/performance.md).
constexpr int kFirstAttemptWithDeformationEachColour = 2;

/// The factor on both under-relaxation parameters in attempt `attempt` of a
/// step: 1, then solver.retry_damping (0.8), then half of that at each
/// further retry.  Most first attempts that fail in the spike phase fail
/// narrowly: at 513^2 (T = 3.40-3.60) a retry at 0.8 converged as every retry
/// at 0.5 did, in 9.9 instead of 13.7 cycles per step (docs/performance.md).
double attempt_damping(int attempt, double retry_damping) {
  if (attempt == 0) return 1.0;
  return retry_damping * std::pow(kFurtherRetryDamping, attempt - 1);
}

/// Thrown after a cycle when the observer asks the run to stop (a signal):
/// the step under way is abandoned, and the run stops after the step before
/// it.  A step may take minutes on a fine grid, or, with a solver.max_cycles
/// of millions and a tolerance it never meets, for ever.  Not a
/// std::exception: the retries, which catch those, must not catch it.
struct StepAbandoned {};

/// Thrown by a cycle whose residual stalled at round-off above the tolerance
/// (stalled_at_round_off): no retry, damping or shorter interval gets below
/// it, and with solver.tolerance = 1e-16 on 33^2 each step spent its attempts
/// and halvings there (29 steps in 300 s).  Not a std::exception, for the
/// same reason as StepAbandoned; solve_step makes it the run's RunFailure.
struct StepAtRoundOff {
  std::string reason;
};

/// The mesh size on which solver.switch_ratio applies as given: that of the
/// default case, 257^2 on [-1.5, 1.5]^2, where it was tuned (3).
constexpr double kSwitchReferenceMesh = 3.0 / 256.0;

/// The relaxation settings of a run: on meshes finer than the reference the
/// switch ratio grows like 1/h, on each multigrid level by that level's own
/// mesh (reynolds::switch_ratio_on).  The flow part of the ratio grows like
/// 1/h^2 and the elastic-squeeze part stays O(1) at dT = h, so with a fixed
/// ratio ever more points near the contact turn Gauss-Seidel as the mesh is
/// refined; Venner & Lubrecht's switch compares the flow with the elastic term
/// over h, which keeps their share.  Measured: at 1025^2 every first attempt
/// of a contact step diverged with 3 and converged in 2-3 cycles with 10 or
/// 30; at 513^2 (T = 3.40-3.60) 6 cut the retried steps from 27 to 8 of 35
/// and the work by 8 %, with the contact phase unchanged; at 257^2, 10 cost
/// 18 % more work than 3.  Coarser meshes keep the ratio as given.  By level,
/// not the finest grid's ratio on every level: the rebound of 1025^2 from
/// T = 3.47 to 3.62 took 52.2 instead of 58.4 work units per step, from
/// T = 3.73 to 3.88 73.0 instead of 75.7 (docs/performance.md).
reynolds::RelaxationSettings relaxation_for(reynolds::RelaxationSettings settings) {
  settings.switch_reference_mesh = kSwitchReferenceMesh;
  return settings;
}

/// The grid the solver works on: the quadrant of the case's grid when the
/// case is even in X and Y, else the case's grid itself.
Grid2D solver_grid(const ImpactConfig& c) {
  const Grid2D full(c.grid_points, c.half_width);
  return is_mirror_symmetric(c) ? full.quadrant() : full;
}

/// f(i, j) = value(i, j) at the interior points, 0 on the boundary.
template <class Value>
void fill_interior(Field& f, const Grid2D& grid, Value&& value) {
  f.fill(0.0);
  const int first = grid.first_interior();
  for (int j = first; j < grid.n - 1; ++j)
    for (int i = first; i < grid.n - 1; ++i) f(i, j) = value(i, j);
}

reynolds::OperatorSettings operator_settings(const ImpactConfig& c) {
  reynolds::OperatorSettings op;
  op.lambda_bar = c.lambda_bar;
  op.elastic = c.elastic;
  op.use_fft = c.deformation == DeformationMethod::Fft;
  op.waviness = {c.waviness_amplitude, c.waviness_wavelength, c.waviness_angle_deg};
  op.face_mean = c.face_mean;
  return op;
}

}  // namespace

struct ImpactProblem::Impl {
  explicit Impl(const ImpactConfig& config);

  RunSummary run(ImpactObserver& observer);

  // Named steps of run().
  void set_time_coefficients(double b0);
  void set_delta(double Delta);
  // How run() starts, checks and ends each step (impact/RunGuards.hpp).
  struct RunProgress {
    BallState ball;
    double force_now = 0.0, force_before = 0.0;
    double edge_force_now = 0.0;  ///< the force of the edge band at the last time level
    bool had_pressure = false;
    int first_step = 1;
    RunBounds bounds;
    double energy = 0.0;  ///< kinetic + elastic energy after the last step
  };
  /// The force at the new time level, whether an attempt converged (else
  /// the best iterate of all attempts is the solution), and the residual and
  /// cycles of the iterate kept.
  struct StepSolve {
    double force = 0.0;
    bool converged = false;
    double residual = 0.0;
    int cycles = 0;
  };
  /// What a time level starts from: enough to solve its interval again, in halves.
  struct IntervalStart {
    Field P, P_before, P_before2, P_before3, rhoH_now, rhoH_old;
    BallState ball;
    double force_now = 0.0, force_before = 0.0, edge_force_now = 0.0, delta = 0.0,
           level_spacing = 0.0, spacing_before = 0.0, spacing_before2 = 0.0;
    int levels_done = 0;
    double impulse = 0.0, edge_impulse = 0.0;  ///< summary's, which accepted intervals add to
    AttemptMemory attempt_memory;              ///< restored only when the step is abandoned
    SplitMemory split_memory;                  ///< the same
  };
  /// Advances `run` by one time step dT (step `step`): as one implicit step,
  /// or in halves when none of its attempts converges.
  void advance_step(int step, RunProgress& run);
  /// Advances `run` over [T, T + dt], `depth` halvings below a whole step,
  /// from `start`, the state of `run` and of the solver now.
  void advance_interval(int step, RunProgress& run, double dt, int depth,
                        const IntervalStart& start);
  /// The best iterate of an interval solved whole, kept should its halves do worse.
  struct WholeInterval {
    Field P;
    double delta = 0.0;
    StepSolve solved;
  };
  /// Advances `run` over [T, T + dt] as two halves, from `start`, the state
  /// of `run` and of the solver now; `whole`: the interval solved whole, kept
  /// should the halves end further above the tolerance.
  void advance_in_halves(int step, RunProgress& run, double dt, int depth,
                         const std::optional<WholeInterval>& whole, const IntervalStart& start);
  struct StepTally;
  void keep_whole_interval(const WholeInterval& whole, const IntervalStart& start,
                           const StepTally& before, RunProgress& run, double dt);
  IntervalStart interval_start(const RunProgress& run) const;
  void restore_interval_start(const IntervalStart& start, RunProgress& run);
  /// Moves the ball and the time levels to the solution `solved` of the interval dt.
  void accept_interval(RunProgress& run, double dt, const StepSolve& solved);
  /// Solves the interval dt from the last time level of `run`.  Throws if
  /// every attempt diverged.
  StepSolve solve_time_step(int step, const RunProgress& run, double dt);
  /// The quasi-static film pressure at T = 0; returns its force, residual and
  /// the rate of its last cycles (check_initial_state judges them).
  InitialSolve solve_initial_pressure();
  /// The residual measure that round-off leaves in the solver's pressure
  /// (round_off_residual).
  [[nodiscard]] double round_off_floor() const {
    return round_off_residual(interior_maximum(grid, solver->solution()).value,
                              grid.full_interior());
  }
  /// Chooses the initial approximation of a step dt = omega x the last one
  /// (the last pressure, its extrapolation in time, or, where both are poor,
  /// the extrapolation in a contracting frame) and returns its residual.
  double choose_start(double omega);
  /// Makes `candidate` the solver's pressure, the step's start, if its
  /// residual is below `residual`, that of the pressure there now (or equal
  /// to it, `on_a_tie`); else leaves both as they were.  Returns the
  /// residual of the start.
  double offer_start(Field& candidate, double residual, bool on_a_tie);
  /// How many of P_before, P_before2, P_before3 lie a step apart before the
  /// last level for a step omega = 1 (the series start), 0 for a start from
  /// the last level or its linear extrapolation only.
  [[nodiscard]] std::size_t earlier_levels_a_step_apart(double omega) const;
  /// P_before3 <- P_before2 <- P_before; P_before is then free for the last level.
  void shift_earlier_levels();
  /// The attempts of one step from the chosen start, whose residual is `start_residual`.
  StepSolve solve_with_retries(int step, const BallState& ball, double start_residual);
  /// The iterate with the smallest residual of a step's attempts so far.
  struct BestIterate {
    Field P;
    double residual = std::numeric_limits<double>::infinity();
    double delta = 0.0;
    int cycles = 0;
    bool vanished = true;  ///< its pressure vanished (may_keep_unconverged); none yet: true
    /// Whether an iterate of this residual, keepable or not, is the better
    /// one: any that may be kept beats one whose pressure vanished.
    [[nodiscard]] bool improves(double r, bool keepable) const {
      if (keepable == vanished) return keepable;
      return r < residual;
    }
  };
  /// How an attempt ended: below the tolerance or not, and its last iterate's
  /// residual and cycles.
  struct AttemptEnd {
    bool converged = false;
    double residual = 0.0;
    int cycles = 0;
  };
  /// The multigrid cycles of one attempt of a step from the current
  /// approximation, whose residual is `attempt.residual`, as long as
  /// judge_attempt lets them go on.  Offers every iterate to `best`.  Throws
  /// on divergence.
  AttemptEnd iterate_time_step(const CycleRecord& attempt, const BallState& ball,
                               BestIterate& best);
  /// Whether a cycle that took the film force from `force_before_cycle` to
  /// `force` changed it by at most solver.force_tolerance of its scale.
  bool force_has_settled(double force, double force_before_cycle) const;
  /// One local Newton step on the finest grid, on windows where its residual
  /// is largest, and the Delta of the new force; taken back if it raises the
  /// residual measure above `residual`, the measure before it.  Returns the
  /// measure after.
  double newton_on_worst_windows(const BallState& ball, double residual);
  /// The step's row; `work_before` is the hierarchy's work units before the step.
  StepRecord make_record(int step, const BallState& ball, double force, double work_before) const;
  /// Hands the step to the observer, with the fields on the full grid.
  void report_step(ImpactObserver& observer, const StepRecord& record, const Field& H,
                   bool snapshot) const;

  void start_at_delta0(RunProgress& run);
  void start_from_restart(RunProgress& run);
  double elastic_energy_now() const;
  /// Int Int P dX dY over the edge band (grid/EdgeBand.hpp).
  double edge_force_of(const Field& P) const;
  /// Throws RunFailure when the step broke a guard; the outcome when the run ends here.
  std::optional<RunOutcome> check_step_end(const StepRecord& record, RunProgress& run);
  /// advance_step, then check_step_end; a failure says what the edge impulse
  /// so far says of the domain (domain_note).
  std::pair<StepRecord, std::optional<RunOutcome>> solve_step(int step, RunProgress& run);
  void add_to_summary(const StepRecord& record);

  ImpactConfig cfg;
  Grid2D grid;
  double dT;
  Newmark newmark;
  ReynoldsHierarchy hierarchy;
  multigrid::FasSolver* solver;  ///< hierarchy's
  Field rhoH_now, rhoH_old;      ///< rho H at the last two time levels (finest grid)
  Field P_before;                ///< pressure of the time level before the last one
  Field P_before2;               ///< ... and of the one before that
  Field P_before3;               ///< ... and of the one before that (the cubic start)
  /// Time between the last two time levels: dT, or a part of it within a split step.
  double level_spacing = 0.0;
  double spacing_before = 0.0;   ///< time between P_before2 and P_before
  double spacing_before2 = 0.0;  ///< time between P_before3 and P_before2
  /// Time levels solved so far, the halves of split steps included (the first
  /// is solved with BDF1, the first two start from the last pressure).
  int levels_done = 0;
  /// What the current step cost and how it ended, over its halves if it was split.
  struct StepTally {
    int cycles = 0, attempts = 0, splits = 0;
    int depth = 0;  ///< the most halvings below dT of an interval accepted
    double residual = 0.0;
    bool retried = false, unconverged = false;
  };
  StepTally tally;
  BdfCoefficients bdf = kBdf1;
  /// The observer of the running run(), told of every cycle (nullptr between runs).
  ImpactObserver* cycle_observer = nullptr;
  /// Throws StepAbandoned when cycle_observer asks the run to stop.
  void throw_if_stop_requested() const {
    if (cycle_observer && cycle_observer->stop_requested()) throw StepAbandoned{};
  }
  /// The state after `step` (full-grid fields, whatever grid the solver
  /// works on: a checkpoint does not depend on solver.symmetry).
  [[nodiscard]] ImpactState state_after(int step, const RunProgress& run) const;
  /// Ends a run asked to stop whose last completed step is `step`: its state
  /// goes to the state sink (none before the first step), then RunInterrupted.
  [[noreturn]] void stop_after(int step, const RunProgress& run);
  std::optional<ImpactState> restart;  ///< where run() starts, when not at Delta0
  int state_every = 0;
  ImpactProblem::StateSink state_sink;
  /// The run's summary so far; the solver counters (unconverged and retried
  /// steps) are kept in it by advance_step.
  RunSummary summary;
  AttemptMemory attempt_memory;  ///< where the next step's attempts begin
  SplitMemory split_memory;      ///< in how many halvings the next step begins
};

ImpactProblem::Impl::Impl(const ImpactConfig& config)
    : cfg(config),
      grid(solver_grid(config)),
      dT(effective_time_step(config)),
      newmark(dT),
      hierarchy(grid, config.lubricant.with_alpha_bar(config.alpha_bar), operator_settings(config),
                relaxation_for(config.relaxation), config),
      solver(&hierarchy.solver()),
      rhoH_now(grid),
      rhoH_old(grid),
      P_before(grid),
      P_before2(grid),
      P_before3(grid) {}

void ImpactProblem::Impl::set_time_coefficients(double b0) { hierarchy.set_time_step(dT, b0); }

void ImpactProblem::Impl::set_delta(double Delta) { hierarchy.set_delta(Delta); }

ImpactProblem::Impl::StepSolve ImpactProblem::Impl::solve_time_step(int step,
                                                                    const RunProgress& run,
                                                                    double dt) {
  const double omega = levels_done > 0 ? dt / level_spacing : 1.0;
  bdf = levels_done == 0 ? kBdf1 : bdf2(omega);  // BDF2 needs two earlier levels: BDF1 starts it
  hierarchy.set_time_step(dt, bdf.b0);
  fill_interior(solver->rhs(), grid, [&](int i, int j) {
    return (bdf.b1 * rhoH_now(i, j) + bdf.b2 * rhoH_old(i, j)) / dt;
  });
  // The separation at the new time follows from the force at the new time
  // (Newmark); the coupling is weak (dDelta/dforce = beta dT^2 3/(2 pi)), so a
  // fixed-point update of Delta after each cycle converges in a few cycles.
  // Its first value comes from the force extrapolated linearly in time.
  newmark = Newmark(dt);
  const double force_guess =
      levels_done >= 2 ? (1.0 + omega) * run.force_now - omega * run.force_before : run.force_now;
  set_delta(newmark.delta_for_force(run.ball, force_guess));
  const double start_residual = choose_start(omega);
  return solve_with_retries(step, run.ball, start_residual);
}

double ImpactProblem::Impl::choose_start(double omega) {
  Field& P = solver->solution();
  Field last = P;  // the last solution: P_before once the levels have shifted
  double residual = solver->residual_norm();
  if (levels_done >= 2) {
    // Linear extrapolation in time of the pressure: the initial approximation
    // is then O(dT^2) from the new solution instead of O(dT) where the
    // pressure is smooth.  Where a narrow peak moves across the mesh it is
    // bounded (PressurePredictor.hpp), and should it still start the step
    // worse than the last solution does, the start with the smaller residual
    // is taken.
    // (Measured on 257^2: fewer stalled steps.  The last solution's residual
    // costs no deformation: the step before ended with its coefficients.)
    const std::array<const Field*, kMaxEarlierLevels> earlier{&P_before, &P_before2, &P_before3};
    const std::size_t series_levels = earlier_levels_a_step_apart(omega);
    const std::span<const Field* const> series = std::span(earlier).first(series_levels);
    Field candidate(grid);
    // Three or four levels a step apart: the series extrapolation, as far as
    // the history is resolved in time (PressurePredictor.hpp).
    if (series_levels >= 2) {
      bounded_series_extrapolation(last, series, candidate);
    } else {
      bounded_extrapolation(last, P_before, omega, candidate);
    }
    residual = offer_start(candidate, residual, true);
    if (cfg.contracting_start && series_levels >= 2 &&
        residual > kContractingStartTrigger * cfg.tolerance) {
      const double contraction = radial_contraction(grid, last, P_before);
      contracting_frame_extrapolation(grid, last, series, contraction, candidate);
      residual = offer_start(candidate, residual, false);
    }
  }
  // The first two levels start from the last solution (the first: the T = 0 pressure).
  shift_earlier_levels();
  P_before = std::move(last);
  return residual;
}

double ImpactProblem::Impl::offer_start(Field& candidate, double residual, bool on_a_tie) {
  Field& P = solver->solution();
  std::swap(P, candidate);
  const double offered = solver->residual_norm();
  if (offered < residual || (on_a_tie && offered == residual)) return offered;
  std::swap(P, candidate);
  return residual;
}

std::size_t ImpactProblem::Impl::earlier_levels_a_step_apart(double omega) const {
  // The series uses the levels from 1 on: level 0 is the quasi-static
  // pressure at T = 0 (solve_initial_pressure), not a time step's.
  if (omega != 1.0 || levels_done < 3 || spacing_before != level_spacing) return 0;
  if (levels_done < 4 || spacing_before2 != level_spacing) return 2;
  return 3;
}

void ImpactProblem::Impl::shift_earlier_levels() {
  std::swap(P_before3, P_before2);
  std::swap(P_before2, P_before);
}

ImpactProblem::Impl::StepSolve ImpactProblem::Impl::solve_with_retries(int step,
                                                                       const BallState& ball,
                                                                       double start_residual) {
  // Cycles until the tolerance.  Should the iteration diverge, lose ground or
  // stall above the tolerance (the highly nonlinear moments: dimple formation,
  // the spike and the collapse of the entrapped pocket before lift-off), the
  // step starts again from the same initial approximation with more damping
  // (attempt_damping), up to kMaxRetries times.  If no attempt converges, the
  // iterate with the smallest residual of all attempts is the result.  The
  // step begins with the attempt the steps before it needed (AttemptMemory).
  const Field start = solver->solution();
  const double start_delta = hierarchy.finest().delta();
  reynolds::ReynoldsOperator& fine = hierarchy.finest();
  BestIterate best;
  const std::vector<int> attempts = attempt_order(attempt_memory.first);
  for (const int attempt : attempts) {
    const bool last_attempt = attempt == attempts.back();
    const double damping = attempt_damping(attempt, cfg.retry_damping);
    hierarchy.set_damping(damping);
    hierarchy.set_deformation_each_colour(cfg.relaxation.deformation_each_colour ||
                                          attempt >= kFirstAttemptWithDeformationEachColour);
    // The retries also guard against coarse-grid corrections that make the
    // residual worse (multigrid/Fas.hpp): on 513^2 the coarse grids cannot
    // represent the spike, and their corrections blew steps up.
    solver->set_correction_safeguard(attempt > 0 ? cfg.correction_safeguard : 0.0);
    AttemptEnd end;
    try {
      const CycleRecord start_of_attempt{
          step, ball.T + newmark.dT(), newmark.dT(), attempt, damping, 0, start_residual};
      end = iterate_time_step(start_of_attempt, ball, best);
    } catch (const std::runtime_error&) {
      // A diverged attempt is never kept (only its iterates before it
      // diverged are candidates); when no attempt had a finite iterate, the
      // run cannot go on.
      if (last_attempt && best.P.size() == 0) throw;
    }
    ++tally.attempts;
    if (attempt != attempts.front()) tally.retried = true;
    if (end.converged) {
      attempt_memory = remember_attempt(attempt_memory, attempt);
      return {fine.force(solver->solution()), true, end.residual, end.cycles};
    }
    if (last_attempt) break;
    solver->solution() = start;
    set_delta(start_delta);
  }
  solver->solution() = best.P;
  set_delta(best.delta);
  fine.update_coefficients(best.P);
  return {fine.force(best.P), false, best.residual, best.cycles};
}

InitialSolve ImpactProblem::Impl::solve_initial_pressure() {
  // At T = 0 the film already carries load: d(rho H)/dT = rho dDelta/dT = -V0
  // (the deformation rate is neglected: with P ~ 1e-2 at Delta0 = 1 it is
  // small, and zero for rigid bodies), so the Reynolds equation becomes
  // div(xi grad P) = -rho V0, solved with the squeeze coefficient switched off.
  // Starting the ball with this force instead of none keeps the first step,
  // and with it the time integration, second order.
  set_time_coefficients(0.0);
  set_delta(cfg.Delta0);
  fill_interior(solver->rhs(), grid, [&](int, int) { return -cfg.V0; });
  solver->solution().fill(0.0);
  // This one solve starts from P = 0, far from its solution, and its
  // piezoviscous-elastic problem can have a second, highly loaded solution:
  // with the deformation once per sweep, the full multigrid of M = 3, L = 10
  // on 65^2 landed on one with 6 times the force (docs/model.md, section 7).  The
  // deformation before each colour keeps it on the lightly loaded branch.
  hierarchy.set_deformation_each_colour(true);
  // It also keeps the Gauss-Seidel under-relaxation at flow-dominated points.
  // At the edge of existence (M <= 10 at L = 20, M <= 3 at L = 10) this solve
  // meets the stopping rule without converging further (129^2, M = 3, L = 20:
  // residual 1.3e-4 after 100 cycles towards 1e-9, with either relaxation), and
  // which of those cases start depended on the relaxation (docs/validation.md,
  // "The map").
  hierarchy.set_omega_flow_dominated(cfg.relaxation.omega_gauss_seidel);
  solver->full_multigrid();
  // Cycles until the stopping rule of the steps holds, the force criterion
  // included: the force at T = 0 sets the ball's first acceleration, and an
  // error in it stays in the first steps whatever they cycle (129^2: 2.5 %
  // at the first step with the residual measure alone here).  The residual
  // aims below the steps' tolerance: the pressure is a solution only if it
  // converges on (kInitialToleranceFactor, RunGuards.hpp).
  reynolds::ReynoldsOperator& fine = hierarchy.finest();
  double force_before_cycle = std::numeric_limits<double>::infinity();
  const double tolerance = kInitialToleranceFactor * cfg.tolerance;
  std::vector<double> residuals;
  bool at_round_off = false;
  for (int c = 1; c <= cfg.max_cycles; ++c) {
    const double force = fine.force(solver->solution());
    const double residual = solver->residual_norm();
    residuals.push_back(residual);
    if (residual < tolerance && force_has_settled(force, force_before_cycle)) break;
    // A tolerance below round-off: no cycle gets nearer (1e-300 cycled for ever).
    at_round_off = stalled_at_round_off(residuals, [&] { return round_off_floor(); });
    if (at_round_off) break;
    force_before_cycle = force;
    solver->cycle();
    if (cycle_observer) cycle_observer->on_initial_cycle(c, residual);
    throw_if_stop_requested();
  }
  hierarchy.set_deformation_each_colour(cfg.relaxation.deformation_each_colour);
  hierarchy.set_omega_flow_dominated(cfg.relaxation.omega_flow_dominated);
  fine.update_coefficients(solver->solution());
  InitialSolve result{fine.force(solver->solution()), solver->residual_norm()};
  if (!residuals.empty()) result.first_residual = residuals.front();
  result.at_round_off = at_round_off;
  residuals.push_back(result.residual);
  result.rate = steady_fall_rate(residuals);
  return result;
}

ImpactProblem::Impl::AttemptEnd ImpactProblem::Impl::iterate_time_step(const CycleRecord& attempt,
                                                                       const BallState& ball,
                                                                       BestIterate& best) {
  reynolds::ReynoldsOperator& fine = hierarchy.finest();
  const int step = attempt.step;
  const double initial_residual = attempt.residual;  // every attempt starts from the same state
  CycleRecord report = attempt;
  if (cycle_observer) cycle_observer->on_cycle(report);
  std::vector<double> history;
  double force_before_cycle = fine.force(solver->solution());
  const double start_force = force_before_cycle;
  for (int c = 1;; ++c) {
    solver->cycle();
    set_delta(newmark.delta_for_force(ball, fine.force(solver->solution())));
    double residual = solver->residual_norm();
    if (cfg.local_newton_half_width > 0 && residual >= cfg.tolerance) {
      residual = newton_on_worst_windows(ball, residual);
    }
    history.push_back(residual);
    report.cycle = c;
    report.residual = residual;
    if (cycle_observer) cycle_observer->on_cycle(report);
    throw_if_stop_requested();
    if (!std::isfinite(residual) || residual > kDivergenceFactor * initial_residual)
      throw RunFailure(fmt::format(
          "{}: the multigrid iteration diverged (residual {}, "
          "{} at the start of the step){}",
          time_step_text(step, ball.T + newmark.dT()), finite_or_text(residual, "{:.3e}"),
          finite_or_text(initial_residual, "{:.3e}"), rigid_film_hint(cfg)));
    if (stalled_at_round_off(history, [&] { return round_off_floor(); }))
      throw StepAtRoundOff{fmt::format("{}: the film pressure {}",
                                       time_step_text(step, ball.T + newmark.dT()),
                                       round_off_text(residual, cfg.tolerance))};
    const double force = fine.force(solver->solution());
    if (const bool keepable = may_keep_unconverged(start_force, force);
        best.improves(residual, keepable)) {
      best.P = solver->solution();
      best.residual = residual;
      best.delta = fine.delta();
      best.cycles = c;
      best.vanished = !keepable;
    }
    const bool force_settled = force_has_settled(force, force_before_cycle);
    force_before_cycle = force;
    switch (judge_attempt(history, cfg.tolerance, cfg.max_cycles, force_settled)) {
      case AttemptVerdict::Converged:
        return {true, residual, c};
      case AttemptVerdict::LostGround:
      case AttemptVerdict::Exhausted:
        return {false, residual, c};
      case AttemptVerdict::Continue:
        break;
    }
  }
}

bool ImpactProblem::Impl::force_has_settled(double force, double force_before_cycle) const {
  if (cfg.force_tolerance == 0.0) return true;
  // The scale: the largest force so far, or the force now if larger (the
  // approach).  Relative to the force now alone, the last steps before
  // lift-off (force -> 0) cost 26 % more cycles in the 513^2 collapse.
  const double scale = std::max(std::abs(force), summary.max_force);
  return !(std::abs(force - force_before_cycle) > cfg.force_tolerance * scale);
}

double ImpactProblem::Impl::newton_on_worst_windows(const BallState& ball, double residual) {
  reynolds::ReynoldsOperator& fine = hierarchy.finest();
  Field& P = solver->solution();
  const reynolds::GlobalUnknown delta{[&] {
                                        set_delta(newmark.delta_for_force(ball, fine.force(P)));
                                        return solver->residual_norm();
                                      },
                                      [&](double Delta) { set_delta(Delta); }};
  return reynolds::newton_on_worst_windows(
      fine, P, solver->rhs(),
      reynolds::window_search(cfg.local_newton_half_width, cfg.local_newton_windows, fine.grid()),
      residual, delta);
}

void ImpactProblem::Impl::advance_step(int step, RunProgress& run) {
  tally = StepTally{};
  const IntervalStart start = interval_start(run);
  try {
    advance_interval(step, run, dT, 0, start);
  } catch (const StepAbandoned&) {
    // The state after the step before, as its checkpoint would have it.
    restore_interval_start(start, run);
    attempt_memory = start.attempt_memory;
    split_memory = start.split_memory;
    throw;
  }
  split_memory = remember_split(split_memory, tally.depth);
  if (tally.splits > 0) {
    // The next step sees the levels T and T + dT, as after an unsplit step.
    rhoH_old = start.rhoH_now;
    P_before = start.P;
    P_before2 = start.P_before;
    P_before3 = start.P_before2;
    spacing_before = spacing_before2 = dT;
    run.force_before = start.force_now;
    run.ball.T = start.ball.T + dT;
    level_spacing = dT;
    levels_done = step;
  }
  if (tally.retried) ++summary.retried_steps;
  if (tally.unconverged) ++summary.unconverged_steps;
}

void ImpactProblem::Impl::advance_interval(int step, RunProgress& run, double dt, int depth,
                                           const IntervalStart& start) {
  if (depth < split_memory.begin.first) {
    // The steps before needed intervals this short: the whole would fail as
    // theirs did (SplitMemory).
    advance_in_halves(step, run, dt, depth, std::nullopt, start);
    return;
  }
  std::optional<StepSolve> solved;
  try {
    solved = solve_time_step(step, run, dt);
  } catch (const std::runtime_error&) {
    if (depth == kMaxSplitDepth) throw;
  }
  if (!solved || (!solved->converged && depth < kMaxSplitDepth)) {
    // Half the time step halves the distance the pocket-collapse spike moves
    // in it (docs/model.md, section 8).
    std::optional<WholeInterval> whole;
    if (solved) whole = WholeInterval{solver->solution(0), hierarchy.finest().delta(), *solved};
    restore_interval_start(start, run);
    tally.retried = true;
    advance_in_halves(step, run, dt, depth, whole, start);
    return;
  }
  if (!solved->converged) tally.unconverged = tally.retried = true;
  accept_interval(run, dt, *solved);
  tally.depth = std::max(tally.depth, depth);
}

void ImpactProblem::Impl::advance_in_halves(int step, RunProgress& run, double dt, int depth,
                                            const std::optional<WholeInterval>& whole,
                                            const IntervalStart& start) {
  const StepTally before = tally;
  ++tally.splits;
  // The halves are judged on their own: an earlier sibling interval of the
  // same step may have been kept above the tolerance already.
  tally.residual = 0.0;
  tally.unconverged = false;
  advance_interval(step, run, 0.5 * dt, depth + 1, interval_start(run));
  advance_interval(step, run, 0.5 * dt, depth + 1, interval_start(run));
  const bool halves_worse = whole && tally.unconverged && tally.residual > whole->solved.residual;
  tally.residual = std::max(tally.residual, before.residual);
  tally.unconverged = tally.unconverged || before.unconverged;
  if (halves_worse) {
    keep_whole_interval(*whole, start, before, run, dt);
    tally.depth = std::max(tally.depth, depth);
  }
}

void ImpactProblem::Impl::keep_whole_interval(const WholeInterval& whole,
                                              const IntervalStart& start, const StepTally& before,
                                              RunProgress& run, double dt) {
  // The halves ended further above the tolerance than the whole interval did
  // (129^2, M = 50, L = 20: 4.2e-3, beyond the 100-times guard, against a
  // whole step within it): the whole interval's best iterate is kept.
  const int attempts = tally.attempts;
  restore_interval_start(start, run);
  tally = before;
  tally.attempts = attempts;
  tally.retried = tally.unconverged = true;
  solver->solution() = whole.P;
  set_delta(whole.delta);
  hierarchy.finest().update_coefficients(whole.P);
  newmark = Newmark(dt);
  accept_interval(run, dt, whole.solved);
}

ImpactProblem::Impl::IntervalStart ImpactProblem::Impl::interval_start(
    const RunProgress& run) const {
  return {solver->solution(0),
          P_before,
          P_before2,
          P_before3,
          rhoH_now,
          rhoH_old,
          run.ball,
          run.force_now,
          run.force_before,
          run.edge_force_now,
          hierarchy.finest().delta(),
          level_spacing,
          spacing_before,
          spacing_before2,
          levels_done,
          summary.impulse,
          summary.edge_impulse,
          attempt_memory,
          split_memory};
}

void ImpactProblem::Impl::restore_interval_start(const IntervalStart& start, RunProgress& run) {
  solver->solution() = start.P;
  P_before = start.P_before;
  P_before2 = start.P_before2;
  P_before3 = start.P_before3;
  rhoH_now = start.rhoH_now;
  rhoH_old = start.rhoH_old;
  run.ball = start.ball;
  run.force_now = start.force_now;
  run.force_before = start.force_before;
  run.edge_force_now = start.edge_force_now;
  set_delta(start.delta);
  level_spacing = start.level_spacing;
  spacing_before = start.spacing_before;
  spacing_before2 = start.spacing_before2;
  levels_done = start.levels_done;
  summary.impulse = start.impulse;
  summary.edge_impulse = start.edge_impulse;
}

void ImpactProblem::Impl::accept_interval(RunProgress& run, double dt, const StepSolve& solved) {
  const double force = solved.force;
  run.ball = newmark.advance(run.ball, force);
  summary.impulse += 0.5 * (run.force_now + force) * dt * kForceToAcceleration;
  const double edge_force = edge_force_of(solver->solution(0));
  summary.edge_impulse += 0.5 * (run.edge_force_now + edge_force) * dt * kForceToAcceleration;
  run.edge_force_now = edge_force;
  run.force_before = run.force_now;
  run.force_now = force;
  const reynolds::ReynoldsOperator& fine = hierarchy.finest();
  const Field& H = fine.film();
  const Field& rho = fine.density();
  rhoH_old = rhoH_now;
  for (std::size_t k = 0; k < H.size(); ++k) rhoH_now[k] = rho[k] * H[k];
  spacing_before2 = spacing_before;
  spacing_before = level_spacing;
  level_spacing = dt;
  ++levels_done;
  tally.cycles += solved.cycles;
  tally.residual = std::max(tally.residual, solved.residual);
}

StepRecord ImpactProblem::Impl::make_record(int step, const BallState& ball, double force,
                                            double work_before) const {
  const Field& P = solver->solution(0);
  const Field& H = hierarchy.finest().film();
  const int n = grid.n;
  const int first = grid.first_interior();
  const int c = grid.mirrored ? 0 : (n - 1) / 2;  // the centre X = Y = 0
  StepRecord r;
  r.step = step;
  r.T = ball.T;
  r.Delta = ball.Delta;
  r.dDelta_dT = ball.V;
  r.force = force;
  r.h_center = H(c, c);
  r.p_center = P(c, c);
  r.h_min = std::numeric_limits<double>::infinity();
  r.p_max = 0.0;
  for (int j = first; j < n - 1; ++j) {
    for (int i = first; i < n - 1; ++i) {
      r.h_min = std::min(r.h_min, H(i, j));
      r.p_max = std::max(r.p_max, P(i, j));
    }
  }
  r.cycles = tally.cycles;
  r.residual = tally.residual;
  r.attempts = tally.attempts;
  r.work = hierarchy.work_units() - work_before;
  return r;
}

void ImpactProblem::Impl::report_step(ImpactObserver& observer, const StepRecord& record,
                                      const Field& H, bool snapshot) const {
  const Field& P = solver->solution();
  if (!grid.mirrored) {
    observer.on_step(record, P, H, snapshot);
    return;
  }
  observer.on_step(record, unfold(P, grid), unfold(H, grid), snapshot);
}

void ImpactProblem::Impl::start_at_delta0(RunProgress& run) {
  // The ball at Delta0 moving towards the flat, with the film pressure that
  // this motion already carries (see solve_initial_pressure).
  run.ball = {0.0, cfg.Delta0, -cfg.V0, 0.0};
  const InitialSolve initial = solve_initial_pressure();
  check_initial_state(initial, cfg);
  const double initial_force = initial.force;
  run.ball.A = kForceToAcceleration * initial_force;
  const Field& H0 = hierarchy.finest().film();
  const Field& rho0 = hierarchy.finest().density();
  for (std::size_t k = 0; k < H0.size(); ++k) rhoH_now[k] = rho0[k] * H0[k];
  rhoH_old = rhoH_now;
  summary = RunSummary{};
  summary.T_lift_off = std::numeric_limits<double>::quiet_NaN();
  summary.rebound_speed = std::numeric_limits<double>::quiet_NaN();
  summary.min_h_center = std::numeric_limits<double>::infinity();
  summary.initial_force = initial_force;
  summary.initial_elastic_energy = elastic_energy_now();
  run.force_now = run.force_before = initial_force;
  run.edge_force_now = edge_force_of(solver->solution(0));
  level_spacing = dT;
  spacing_before = spacing_before2 = 0.0;
  levels_done = 0;
  attempt_memory = {};
  split_memory = {};
  run.bounds = run_bounds(cfg, dT, summary.initial_elastic_energy);
}

void ImpactProblem::Impl::start_from_restart(RunProgress& run) {
  // The state a checkpoint stored: the time levels, the ball and the summary
  // so far; the multigrid hierarchy starts from the last pressure.
  ImpactState& s = *restart;
  run.bounds = run_bounds(cfg, dT, s.summary.initial_elastic_energy);
  run.ball = s.ball;
  run.force_now = s.force;
  run.force_before = s.force_before;
  run.had_pressure = s.had_pressure;
  summary = s.summary;
  attempt_memory = s.attempts;
  split_memory = s.splits;
  solver->solution() = fold(s.P, grid);
  P_before = fold(s.P_before, grid);
  P_before2 = fold(s.P_before2, grid);
  P_before3 = fold(s.P_before3, grid);
  rhoH_now = fold(s.rhoH, grid);
  rhoH_old = fold(s.rhoH_before, grid);
  run.first_step = s.step + 1;
  level_spacing = dT;  // every checkpointed step ends at levels dT apart (advance_step)
  spacing_before = spacing_before2 = dT;
  levels_done = s.step;
  // Each step ends with the coefficients of its pressure, and the start of
  // the next one reuses them (choose_start): a restarted run computes them
  // here, outside the work of its first step, which is then the same.
  hierarchy.finest().update_coefficients(solver->solution());
  run.edge_force_now = edge_force_of(solver->solution());
  restart.reset();
}

double ImpactProblem::Impl::edge_force_of(const Field& P) const {
  return edge_band_sum(grid, P) * grid.h() * grid.h();
}

double ImpactProblem::Impl::elastic_energy_now() const {
  const reynolds::ReynoldsOperator& fine = hierarchy.finest();
  return elastic_energy(grid, solver->solution(0), fine.deformation());
}

std::optional<RunOutcome> ImpactProblem::Impl::check_step_end(const StepRecord& record,
                                                              RunProgress& run) {
  const reynolds::ReynoldsOperator& fine = hierarchy.finest();
  check_step_physics(record, run.bounds, cfg, film_minimum(grid, solver->solution(0), fine.film()));
  if (record.p_max > 0.0) run.had_pressure = true;
  const double energy = elastic_energy_now();
  run.energy = 0.5 * record.dDelta_dT * record.dDelta_dT + energy;
  // A run to a given time.T_end goes on to it, at rest or not.
  const bool until_lift_off = !std::isfinite(cfg.T_end);
  if (until_lift_off && is_at_rest(record.dDelta_dT, energy, run.bounds)) return RunOutcome::AtRest;
  if (run.had_pressure && record.p_max <= 0.0 && record.residual > cfg.tolerance)
    throw RunFailure(fmt::format(
        "{}: the pressure vanished in a step that no attempt converged "
        "(residual {:.3g}, above solver.tolerance = {:g}): not a lift-off the solver can vouch "
        "for; the collapse of the entrapped pocket before lift-off is near-singular on fine "
        "grids (docs/performance.md): more cycles (solver.max_cycles) or a coarser grid may "
        "solve it",
        time_step_text(record.step, record.T), record.residual, cfg.tolerance));
  if (run.had_pressure && record.dDelta_dT > 0.0 && record.p_max <= 0.0) return RunOutcome::LiftOff;
  if (record.T >= cfg.T_end - kEndTimeSlack * dT) return RunOutcome::TEnd;
  check_step_cap(record, cfg, dT);
  return std::nullopt;
}

std::pair<StepRecord, std::optional<RunOutcome>> ImpactProblem::Impl::solve_step(int step,
                                                                                 RunProgress& run) {
  const double work_before = hierarchy.work_units();
  try {
    advance_step(step, run);
    const StepRecord record = make_record(step, run.ball, run.force_now, work_before);
    return {record, check_step_end(record, run)};
  } catch (const RunFailure& e) {
    const std::string note = domain_note(summary.edge_impulse, cfg);
    if (note.empty()) throw;
    throw RunFailure(fmt::format("{}; by then {}", e.what(), note));
  } catch (const StepAtRoundOff& e) {
    throw RunFailure(e.reason);
  }
}

void ImpactProblem::Impl::add_to_summary(const StepRecord& record) {
  summary.steps = record.step;
  summary.T_final = record.T;
  if (record.force > summary.max_force) {
    summary.max_force = record.force;
    summary.T_max_force = record.T;
  }
  if (record.h_center < summary.min_h_center) {
    summary.min_h_center = record.h_center;
    summary.T_min_h_center = record.T;
  }
}

ImpactState ImpactProblem::Impl::state_after(int step, const RunProgress& run) const {
  return ImpactState{step,
                     run.ball,
                     run.force_now,
                     run.force_before,
                     run.had_pressure,
                     summary,
                     attempt_memory,
                     split_memory,
                     unfold(solver->solution(), grid),
                     unfold(P_before, grid),
                     unfold(P_before2, grid),
                     unfold(P_before3, grid),
                     unfold(rhoH_now, grid),
                     unfold(rhoH_old, grid)};
}

void ImpactProblem::Impl::stop_after(int step, const RunProgress& run) {
  // A state before the first step cannot be continued (restart_from).
  if (state_sink && step >= 1) state_sink(state_after(step, run));
  throw RunInterrupted(step, run.ball.T);
}

RunSummary ImpactProblem::Impl::run(ImpactObserver& observer) {
  const auto start = std::chrono::steady_clock::now();
  // The cycles of the steps are reported to this run's observer, and to no
  // one once run() has returned or thrown.
  struct ForgetObserver {
    ImpactObserver*& slot;
    ~ForgetObserver() { slot = nullptr; }
  };
  cycle_observer = &observer;
  const ForgetObserver forget{cycle_observer};
  observer.on_start(grid.full());
  RunProgress run;
  try {
    if (restart) {
      start_from_restart(run);
    } else {
      start_at_delta0(run);
    }
  } catch (const StepAbandoned&) {
    stop_after(0, run);
  }
  BallState& ball = run.ball;
  for (int step = run.first_step;; ++step) {
    std::pair<StepRecord, std::optional<RunOutcome>> solved;
    try {
      solved = solve_step(step, run);
    } catch (const StepAbandoned&) {
      stop_after(step - 1, run);
    }
    const auto& [record, end] = solved;
    const Field& H = hierarchy.finest().film();
    const bool snapshot = step % cfg.snapshot_every == 0 || end.has_value();
    report_step(observer, record, H, snapshot);
    add_to_summary(record);
    const bool stop = !end && observer.stop_requested();  // e.g. SIGINT: checkpoint, then stop
    if (stop) stop_after(step, run);
    // Every K-th step, and the last of a run that reached time.T_end: a
    // restart with a later T_end continues it.  After lift-off or rest there
    // is nothing to continue.
    const bool checkpointed =
        state_every > 0 && (end ? *end == RunOutcome::TEnd : step % state_every == 0);
    if (state_sink && checkpointed) state_sink(state_after(step, run));
    if (end) {
      summary.outcome = *end;
      summary.final_energy = run.energy / (0.5 * cfg.V0 * cfg.V0);
      summary.warnings = run_warnings(summary, cfg);
      if (*end == RunOutcome::LiftOff) {
        summary.lifted_off = true;
        summary.T_lift_off = ball.T;
        summary.rebound_speed = ball.V;
      }
      break;
    }
  }
  summary.wall_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  observer.on_finish(summary);
  return summary;
}

ImpactProblem::ImpactProblem(const ImpactConfig& config) : impl_(std::make_unique<Impl>(config)) {}
ImpactProblem::~ImpactProblem() = default;
RunSummary ImpactProblem::run(ImpactObserver& observer) { return impl_->run(observer); }
const ImpactConfig& ImpactProblem::config() const { return impl_->cfg; }

void ImpactProblem::restart_from(ImpactState state) {
  const Grid2D grid = impl_->grid.full();
  for (const Field* f : {&state.P, &state.P_before, &state.P_before2, &state.P_before3, &state.rhoH,
                         &state.rhoH_before}) {
    if (f->n() != grid.n || f->size() != grid.size())
      throw std::invalid_argument(
          fmt::format("restart: the state's fields have {} points per side, the problem's grid {}",
                      f->n(), grid.n));
  }
  if (state.step < 1) throw std::invalid_argument("restart: the state is before the first step");
  impl_->restart = std::move(state);
}

void ImpactProblem::set_state_sink(int every, StateSink sink) {
  impl_->state_every = every;
  impl_->state_sink = std::move(sink);
}

}  // namespace ehlsim
