#include "rolling/RollingProblem.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cmath>
#include <iterator>
#include <limits>
#include <numbers>
#include <optional>
#include <string>
#include <utility>

#include "grid/EdgeBand.hpp"
#include "grid/FieldExtrema.hpp"
#include "grid/NumberText.hpp"
#include "multigrid/Fas.hpp"
#include "reynolds/LocalNewton.hpp"
#include "reynolds/ReynoldsHierarchy.hpp"
#include "rolling/DryEllipticHertz.hpp"
#include "rolling/FilmFormula.hpp"

namespace ehlsim {

namespace {
/// d(force) / dH0 of the dry Hertz contact in these units: the load grows as
/// the approach^(3/2), with approach 1 at load 2 pi / 3, so -dF/dH0 = pi.
constexpr double kLoadStiffness = std::numbers::pi;
/// Rigid bodies (body.elastic = false): the film is H0 + X^2/2 + D Y^2/2 and
/// does not flatten, so the dry stiffness above means nothing (it drove H0
/// negative in the first cycle of M = 10, L = 0).  Scaling the Reynolds
/// equation with X, Y ~ H0^(1/2), H ~ H0 gives P ~ lambda_bar H0^(-3/2) and
/// the force F ~ lambda_bar H0^(-1/2) (isoviscous, an unbounded domain): H0
/// = H0 (F / F0)^2 balances the force exactly under that law, and it keeps
/// H0 positive whatever the force error.  A piezoviscous rigid contact is
/// stiffer (F grows faster as H0 falls), so the exponent 2 is an upper
/// bound of the step; the overshoot rule below damps it.
constexpr double kRigidForceExponent = 2.0;
/// The force ratio of the rigid update is clipped to [1/kRigidForceRatio,
/// kRigidForceRatio]: no more than a 16-fold change of H0 per cycle.
constexpr double kRigidForceRatio = 4.0;
/// The full multigrid starts on the coarsest grid whose mesh is at most the
/// dry contact's smaller semi-axis over this: on a coarser grid the contact
/// lies between a few points.  D = 0.1, M = 20 on a domain four times the
/// default (24 a wide, 1025^2) diverged at the third cycle of its 33^2 stage,
/// where the semi-axis along X (0.648) is 0.86 meshes; started on 65^2 (1.7
/// meshes) it converges.  The default ball starts on 17^2 (2.7 meshes), D =
/// 4 there with 1.3 meshes across the rolling.
constexpr double kStartMeshesPerSemiAxis = 1.0;
/// A stage whose residual grows this far above its first cycle's has diverged.
constexpr double kDivergenceFactor = 1e3;
/// ... as has one whose force is off by the whole load (all pressure gone, or doubled).
constexpr double kDivergedForceError = 1.0;
/// A share of the load below which a diverged balance is said to carry none of it.
constexpr double kNoLoadCarried = 1e-3;
/// Under-relaxation factors of the attempts of a stage: a diverged or stalled
/// stage starts again (kProgressFactor says from where) with more damping.
constexpr double kAttemptDamping[] = {1.0, 0.5, 0.25};
/// A retry undoes a coarse-grid correction that raises the residual more than
/// tenfold (multigrid::FasSettings::correction_safeguard; the impact's retries
/// use the same 10).  M = 50, L = 20 on 513^2: the second cycle from the
/// interpolated 257^2 solution took the residual from 0.4 to 3e5 at full
/// relaxation, 0.3 to 1e9 at half and 0.07 to 2.4 at a quarter; with the
/// safeguard the half relaxation converges.
constexpr double kRetryCorrectionSafeguard = 10.0;
/// A retry starts from the best iterate of the stage so far when that is this
/// factor below the residual of the stage's start, else from the start: M =
/// 20, L = 20 on 513^2 stalled at half relaxation at 1.2e-4, after 75
/// cycles, and started again from the 257^2 solution could not converge in
/// what was left of solver.max_cycles.  An attempt that never got far below
/// its start (full relaxation oscillating about the start's level) leaves a
/// worse start than the interpolated one (M = 50, L = 20, 257^2 on half the
/// domain: 53 cycles from its best iterate, 34 from the start).
constexpr double kProgressFactor = 10.0;
/// The finest stage has stalled when its residual has not reached a new
/// lowest value for this many cycles: it starts again with more damping.
/// M = 1000, L = 20 on 513^2 oscillated about 1e-3 for 40 cycles at full
/// relaxation and converges in 18 at half.  Converging runs set a new lowest
/// residual nearly every cycle, but near the tolerance the outlet spike can
/// make it wobble: M = 20, L = 20 on 513^2 at half relaxation set 1.24e-4 at
/// cycle 75 and 1.04e-4 ten cycles later (8 cycles ended that attempt there).
constexpr int kStallCycles = 12;
/// The Newton step of H0 overshoots when the force error changes sign and
/// keeps more than this fraction of its size: the step is then halved, down
/// to kMinH0Step of solver.h0_relaxation.  At L = 20 the piezoviscous contact
/// is about twice as stiff as the dry one (-dF/dH0 ~ 2 pi, not pi): the force
/// error alternated at -0.9 per cycle on 257^2 (M = 50).
constexpr double kOvershootRatio = 0.5;
constexpr double kMinH0Step = 0.25;
/// ... and doubled again (up to the full step) after this many cycles in a
/// row whose force error kept its sign and fell by less than half while the
/// residual was within kForceLeftFactor of the tolerance: a step halved in
/// the rough first cycles of a grid otherwise stays small when only the force
/// is left to converge.  M = 10, L = 20 on 513^2 ended with exit 1: residual
/// 7e-6 from cycle 90 on, force error 1.2e-4 to 1.9e-5 over the last 30
/// cycles at a quarter step.  While the pressure is far from converged its
/// force lags H0 by several cycles, and a larger step makes the loop
/// unstable (M = 1000, L = 0 on 257^2 diverged with the regrowth at any
/// residual).
constexpr int kH0StepRegrowCycles = 3;
constexpr double kForceLeftFactor = 10.0;

/// A result whose edge band (kEdgeBand) carries more than this share of the
/// load gets a warning: its film depends on the domain.  Hc when the default
/// domain is doubled in both directions at the same mesh (129^2 against
/// 257^2; docs/validation.md, "The load at the domain's edges"): M = 2,
/// L = 0 (3.1 % in the band) +56 %; M = 5, L = 0 (1.3 %) +6 %; M = 3, L = 10
/// (1.8 %) +2.1 %; M = 5, L = 10 (1.1 %) +1.4 %; M = 10, L = 5 (0.58 %)
/// +0.6 % on a domain four times the default's.
constexpr double kEdgeLoadWarning = 0.01;

/// What an edge load share says of the domain: a sentence above
/// kEdgeLoadWarning, else "".  A non-finite pressure gives a share of 0 or
/// NaN (edge_load_share), so no sentence.
std::string domain_note(double edge_load) {
  if (!(edge_load > kEdgeLoadWarning)) return {};
  return fmt::format(
      "{:.1f} % of the load lies within a tenth of the domain's side from its inlet and side "
      "edges (more than {:g} %): the film depends on the domain; extend it (grid.x_min, "
      "grid.y_min, grid.y_max) and compare",
      100.0 * edge_load, 100.0 * kEdgeLoadWarning);
}

/// An elastic result whose Hc differs from the Nijenbanning-Venner-Moes
/// formula by more than this share gets a warning.  The converged films of
/// the chart (M = 10 to 1000, L = 5 to 20, D = 1) are within 11.6 % of it on
/// 257^2 (M = 1000, L = 5, the grid's: 2.6 % on 513^2) and 5.5 % on 513^2;
/// M = 100, L = 10 on 33^2 is 51 % below it (docs/validation.md, "The whole
/// chart").
constexpr double kFormulaDeviationWarning = 0.15;

/// What a deviation `deviation` (relative) from the film formula says of
/// the case: a sentence above kFormulaDeviationWarning, else "".  Named
/// causes: a lubricant the formula is not for, an elongated contact (D > 1:
/// +24 % at D = 4, docs/validation.md, "Elliptic contacts"), the grid.
std::string formula_note(const RollingConfig& c, double deviation) {
  if (!(std::abs(deviation) > kFormulaDeviationWarning)) return {};
  std::string causes;
  const Lubricant& lub = c.lubricant;
  if (lub.viscosity != ViscosityModel::Barus || lub.density != DensityModel::Incompressible)
    causes += "the formula is for a Barus, incompressible lubricant; ";
  if (c.D > 1.0)
    causes +=
        "for D = Rx/Ry > 1 the film falls more slowly with D than the formula's (+24 % at "
        "D = 4); ";
  return fmt::format(
      "Hc is {:+.0f} % from the Nijenbanning-Venner-Moes formula (converged films of a ball "
      "with a Barus lubricant are within 6 % of it on 513^2): {}a grid too coarse for the film "
      "gives such differences too: compare with more grid.points",
      100.0 * deviation, causes);
}

/// A measure at round-off: solver.tolerance = 1e-300 on 33^2 sat at 2.7e-16,
/// where the last cycles' noise made it look converging or stalled by turns.
constexpr double kRoundOffResidual = 1e-13;

/// Defined with the hints below.
double stall_measure(const RollingCycle& c);
bool stalled(const std::vector<RollingCycle>& history);
std::string round_off_text(const RollingConfig& c, const RollingCycle& last);

/// Thrown by a stage whose iteration diverged (caught by the retries).
struct StageDiverged : RollingFailure {
  using RollingFailure::RollingFailure;
};

/// Thrown when the finest grid's iteration, neither diverged nor stalled in
/// its last attempt, is still above the tolerance after solver.max_cycles.
struct CyclesExhausted : RollingFailure {
  using RollingFailure::RollingFailure;
};

/// Thrown when the finest grid's iteration stalled at round-off above the
/// tolerance: more cycles, or the other deformation update, cannot help.
/// solver.tolerance = 1e-300 with solver.max_cycles = 100000 on 33^2 cycled
/// for minutes (both updates) before it said so.
struct AtRoundOff : RollingFailure {
  using RollingFailure::RollingFailure;
};

/// Thrown when the converged film is negative: its message has the hint.
struct NegativeFilm : RollingFailure {
  using RollingFailure::RollingFailure;
};

/// Bilinear interpolation of f at (x, y) inside the grid.
double value_at(const Field& f, const Grid2D& grid, double x, double y) {
  const double h = grid.h();
  const double s = (x - grid.x(0)) / h, t = (y - grid.y(0)) / h;
  const int i = std::clamp(static_cast<int>(std::floor(s)), 0, grid.n - 2);
  const int j = std::clamp(static_cast<int>(std::floor(t)), 0, grid.n - 2);
  const double a = s - i, b = t - j;
  return (1 - a) * (1 - b) * f(i, j) + a * (1 - b) * f(i + 1, j) + (1 - a) * b * f(i, j + 1) +
         a * b * f(i + 1, j + 1);
}

reynolds::OperatorSettings operator_settings(const RollingConfig& c) {
  reynolds::OperatorSettings op;
  op.lambda_bar = c.lambda_bar;
  op.elastic = c.elastic;
  op.use_fft = c.deformation == DeformationMethod::Fft;
  op.face_mean = c.face_mean;
  op.wedge = 1.0;
  op.curvature_ratio = c.D;
  return op;
}

/// The central film of the Nijenbanning-Venner-Moes formula in Hertz units;
/// for rigid bodies the formula without its elastic terms (the full one puts
/// H0 four times too high at M = 10, L = 0).
double formula_central_film(const RollingConfig& c) {
  const double moes =
      c.elastic ? nvm_central_film(c.M, c.L, c.D) : nvm_rigid_central_film(c.M, c.L, c.D);
  return moes_to_hertz_film(moes, c.M);
}

}  // namespace

double widest_resolving_mesh(const RollingConfig& config) {
  const EllipticHertzContact hz = dry_elliptic_hertz(config.D);
  return std::min(hz.ax, hz.ay) / kStartMeshesPerSemiAxis;
}

Grid2D RollingProblem::grid_of(const RollingConfig& c) {
  const double half = 0.5 * (c.x_max - c.x_min);
  return Grid2D(c.grid_points, half, false, {0.5 * (c.x_min + c.x_max), 0.5 * (c.y_min + c.y_max)});
}

struct RollingProblem::Impl {
  explicit Impl(const RollingConfig& config);

  /// The level the full multigrid starts on (kStartMeshesPerSemiAxis).
  [[nodiscard]] int start_level();
  /// The dry Hertz pressure on `level` and H0 from the film formula.
  void start_from_hertz(int level);
  /// A solution of a stage and its residual.
  struct Iterate {
    Field P;
    double h0 = 0.0;
    double residual = std::numeric_limits<double>::infinity();
  };
  /// One attempt of a stage: its index in kAttemptDamping, the most cycles
  /// it may take, and whether it gives up when it stalls.
  struct Attempt {
    int index = 0;
    int cycles = 0;
    bool detect_stall = false;
  };
  /// The cycles of `attempt` on `level` (the finest of the sub-hierarchy)
  /// with H0 updated after each; true when the finest grid reached the
  /// tolerance.  Throws StageDiverged when it diverges, or (detect_stall)
  /// stalls on the finest grid.  Keeps the lowest-residual iterate in `best`.
  bool converge_on(int level, const Attempt& attempt, Iterate& best, const CycleMonitor& monitor);
  /// Why `record` ends its stage as diverged ("" when it does not); `first`
  /// is the residual of the stage's first cycle.
  [[nodiscard]] std::string divergence(const RollingCycle& record, double first) const;
  /// One cycle of `attempt` on `level` and its record, numbered after the
  /// level's earlier cycles.
  RollingCycle cycle_on(int level, int attempt);
  /// One local Newton step on the finest grid after a cycle that left it at
  /// `residual` (H0 stays: the next cycle balances the force); returns the
  /// residual measure after it.
  double newton_on_worst_windows(double residual);
  /// converge_on with retries at more damping when the stage diverges.
  bool solve_stage(int level, int cycles, const CycleMonitor& monitor);
  void update_h0(int level);
  void set_h0(double H0);
  [[nodiscard]] RollingResult result() const;
  /// "; " and domain_note of the pressure of the level last cycled on, or "".
  [[nodiscard]] std::string domain_hint();

  RollingConfig cfg;
  Grid2D grid;
  ReynoldsHierarchy hierarchy;
  multigrid::FasSolver* solver;  ///< hierarchy's
  double h0 = 0.0;
  double h0_step = 1.0;    ///< fraction of solver.h0_relaxation, halved on overshoot
  int slow_same_sign = 0;  ///< cycles in a row whose force error fell slowly, one sign
  std::vector<RollingCycle> history;
  int level_cycles = 0;  ///< cycles on the current level, over all its attempts
};

RollingProblem::Impl::Impl(const RollingConfig& config)
    : cfg(config),
      grid(grid_of(config)),
      hierarchy(grid, config.lubricant.with_alpha_bar(config.alpha_bar), operator_settings(config),
                config.relaxation, config),
      solver(&hierarchy.solver()) {
  hierarchy.set_time_step(1.0, 0.0);  // steady: no squeeze term
}

void RollingProblem::Impl::set_h0(double H0) {
  h0 = H0;
  hierarchy.set_delta(H0);
}

int RollingProblem::Impl::start_level() {
  int level = solver->num_levels() - 1;
  // A rigid contact has no dry ellipse: its start is rough on any grid.
  if (!cfg.elastic) return level;
  const double widest = widest_resolving_mesh(cfg);
  while (level > 0 && hierarchy.level(level).grid().h() > widest) --level;
  return level;
}

void RollingProblem::Impl::start_from_hertz(int start) {
  ReynoldsFasLevel& level = hierarchy.level(start);
  const Grid2D& g = level.grid();
  Field& P = solver->solution(start);
  const EllipticHertzContact hz = dry_elliptic_hertz(cfg.D);
  for (int j = 1; j < g.n - 1; ++j) {
    for (int i = 1; i < g.n - 1; ++i) {
      const double x = g.x(i) / hz.ax, y = g.y(j) / hz.ay;
      P(i, j) = hz.p0 * std::sqrt(std::max(0.0, 1.0 - x * x - y * y));
    }
  }
  // H0 puts the central film of the Hertz pressure at the formula's value.
  set_h0(0.0);
  level.op().update_coefficients(P);
  const double hc_formula = formula_central_film(cfg);
  set_h0(hc_formula - value_at(level.op().film(), g, 0.0, 0.0));
}

void RollingProblem::Impl::update_h0(int level) {
  const double error = hierarchy.level(level).op().force(solver->solution(level)) - kRollingLoad;
  if (!history.empty() && history.back().points == hierarchy.level(level).op().grid().n) {
    const double previous = history.back().force_error * kRollingLoad;
    const bool fell_little = std::abs(error) > kOvershootRatio * std::abs(previous);
    if (error * previous < 0.0 && fell_little) h0_step = std::max(kMinH0Step, 0.5 * h0_step);
    const bool force_left = history.back().residual < kForceLeftFactor * cfg.tolerance;
    slow_same_sign = error * previous > 0.0 && fell_little && force_left ? slow_same_sign + 1 : 0;
    if (slow_same_sign == kH0StepRegrowCycles) {
      h0_step = std::min(1.0, 2.0 * h0_step);
      slow_same_sign = 0;
    }
  } else {
    slow_same_sign = 0;
  }
  if (!cfg.elastic) {
    const double ratio =
        std::clamp((kRollingLoad + error) / kRollingLoad, 1.0 / kRigidForceRatio, kRigidForceRatio);
    double next = h0 * std::pow(ratio, kRigidForceExponent * h0_step * cfg.h0_relaxation);
    // A coarse level of the full multigrid start whose mesh is wider than
    // the pressure zone cannot carry the load at any H0: its force saturates
    // and H0 fell towards zero (M = 20, L = 0: 1e-9 on 33^2), a start the
    // next level diverged from.  There H0 stays at the film whose zone
    // sqrt(2 H0) is one mesh; the finest grid has no such floor.
    if (level > 0) {
      const double mesh = hierarchy.level(level).op().grid().h();
      next = std::max(next, 0.5 * mesh * mesh);
    }
    set_h0(next);
    return;
  }
  set_h0(h0 + h0_step * cfg.h0_relaxation * error / kLoadStiffness);
}

RollingCycle RollingProblem::Impl::cycle_on(int level, int attempt) {
  reynolds::ReynoldsOperator& op = hierarchy.level(level).op();
  solver->cycle(level);
  update_h0(level);
  RollingCycle record;
  record.points = op.grid().n;
  record.cycle = ++level_cycles;
  record.attempt = attempt;
  record.damping = kAttemptDamping[attempt];
  record.residual = solver->residual_norm(level);
  if (level == 0 && cfg.local_newton_half_width > 0 && record.residual >= cfg.tolerance)
    record.residual = newton_on_worst_windows(record.residual);
  record.force_error = (op.force(solver->solution(level)) - kRollingLoad) / kRollingLoad;
  record.Hc = value_at(op.film(), op.grid(), 0.0, 0.0);
  record.H0 = h0;
  record.work = hierarchy.work_units();
  record.each_colour = cfg.relaxation.deformation_each_colour;
  history.push_back(record);
  return record;
}

double RollingProblem::Impl::newton_on_worst_windows(double residual) {
  reynolds::ReynoldsOperator& fine = hierarchy.finest();
  const reynolds::GlobalUnknown fixed_h0{[&] { return solver->residual_norm(0); },
                                         [&](double H0) { set_h0(H0); }};
  return reynolds::newton_on_worst_windows(
      fine, solver->solution(0), solver->rhs(0),
      reynolds::window_search(cfg.local_newton_half_width, cfg.local_newton_windows, fine.grid()),
      residual, fixed_h0);
}

std::string RollingProblem::Impl::divergence(const RollingCycle& record, double first) const {
  const bool iteration = !std::isfinite(record.residual) || !std::isfinite(h0) ||
                         record.residual > kDivergenceFactor * first;
  if (iteration) {
    return fmt::format(
        "the multigrid iteration diverged on the {}^2 grid at cycle {} (residual {}, "
        "force error {})",
        record.points, record.cycle, finite_or_text(record.residual, "{:.3e}"),
        finite_or_text(record.force_error, "{:.3g}"));
  }
  if (!(std::abs(record.force_error) >= kDivergedForceError)) return {};
  // The pressure may have converged to a film that carries none of the load
  // (M = 1e-3 on 33^2: residual 6e-20, force error -1): the balance is what failed.
  const double carried = 1.0 + record.force_error;
  return fmt::format(
      "the force balance diverged on the {}^2 grid at cycle {}: the film carries {} "
      "(force error {:.3g}; residual {:.3e})",
      record.points, record.cycle,
      carried < kNoLoadCarried ? std::string("none of the load")
                               : fmt::format("{:.3g} times the load", carried),
      record.force_error, record.residual);
}

bool RollingProblem::Impl::converge_on(int level, const Attempt& attempt, Iterate& best,
                                       const CycleMonitor& monitor) {
  double first = 0.0, lowest = std::numeric_limits<double>::infinity();
  int lowest_cycle = 0;
  for (int c = 1; c <= attempt.cycles; ++c) {
    const RollingCycle record = cycle_on(level, attempt.index);
    if (monitor) monitor(record);
    if (c == 1) first = record.residual;
    if (std::string why = divergence(record, first); !why.empty()) throw StageDiverged(why);
    if (record.residual < lowest) {
      lowest = record.residual;
      lowest_cycle = c;
    }
    if (record.residual < best.residual) best = {solver->solution(level), h0, record.residual};
    if (attempt.detect_stall && c - lowest_cycle >= kStallCycles)
      throw StageDiverged(fmt::format(
          "the multigrid iteration stalled on the {}^2 grid: residual {:.3e} at cycle {}, "
          "no lower than {:.3e} {} cycles before",
          record.points, record.residual, record.cycle, lowest, c - lowest_cycle));
    if (level == 0 && record.residual < cfg.tolerance &&
        std::abs(record.force_error) < cfg.tolerance)
      return true;
    if (level == 0 && stall_measure(record) < kRoundOffResidual && stalled(history))
      throw AtRoundOff(fmt::format("not converged on the {}^2 grid after {} cycles{}",
                                   record.points, record.cycle, round_off_text(cfg, record)));
  }
  return false;
}

bool RollingProblem::Impl::solve_stage(int level, int cycles, const CycleMonitor& monitor) {
  const Iterate start{solver->solution(level), h0, solver->residual_norm(level)};
  Iterate best = start;
  level_cycles = 0;
  for (int attempt = 0;; ++attempt) {
    const bool last = attempt + 1 == std::ssize(kAttemptDamping);
    hierarchy.set_damping(kAttemptDamping[attempt]);
    solver->set_correction_safeguard(attempt > 0 ? kRetryCorrectionSafeguard : 0.0);
    // On the finest grid solver.max_cycles bounds the cycles of all attempts;
    // the last attempt has what is left and may stall.
    const int budget = level == 0 ? cycles - level_cycles : cycles;
    if (budget <= 0) return false;
    try {
      return converge_on(level, {attempt, budget, level == 0 && !last}, best, monitor);
    } catch (const StageDiverged&) {
      if (last) throw;
    }
    const Iterate& restart = best.residual * kProgressFactor < start.residual ? best : start;
    solver->solution(level) = restart.P;
    set_h0(restart.h0);
  }
}

std::string RollingProblem::Impl::domain_hint() {
  if (history.empty()) return {};
  int level = 0;
  while (level + 1 < solver->num_levels() &&
         hierarchy.level(level).grid().n != history.back().points)
    ++level;
  const std::string note =
      domain_note(edge_load_share(hierarchy.level(level).grid(), solver->solution(level)));
  // M = 1, L = 0 on the default domain: 4 % of the load at the edges, and a
  // film that keeps growing with the domain (docs/validation.md).
  return note.empty() ? note : "; " + note;
}

namespace {
/// Why no grid resolves a rigid contact, else "" (defined below).
std::string unresolvable_rigid_hint(const RollingConfig& c);
}  // namespace

RollingResult RollingProblem::Impl::result() const {
  const reynolds::ReynoldsOperator& op = hierarchy.finest();
  RollingResult r;
  r.grid = grid;
  r.P = solver->solution(0);
  r.H = op.film();
  r.Hc = value_at(r.H, grid, 0.0, 0.0);
  const PointValue film = interior_minimum(grid, r.H);
  const PointValue peak = interior_maximum(grid, r.P);
  r.Hm = film.value;
  r.X_Hm = film.x;
  r.Y_Hm = film.y;
  r.P_max = peak.value;
  r.X_P_max = peak.x;
  r.Y_P_max = peak.y;
  r.H0 = h0;
  r.history = history;
  r.residual = history.back().residual;
  r.force_error = history.back().force_error;
  r.cycles = history.back().cycle;  // on the finest grid, over all its attempts
  r.work = hierarchy.work_units();
  r.each_colour = cfg.relaxation.deformation_each_colour;
  r.edge_load = edge_load_share(grid, r.P);
  if (std::string note = domain_note(r.edge_load); !note.empty()) {
    // A rigid contact no grid resolves (D = 1e-7: Hc 0.008 against the
    // formula's 1.45e5) was told to extend the domain, which cannot help.
    const std::string none = cfg.elastic ? std::string() : unresolvable_rigid_hint(cfg);
    r.warnings.push_back(none.empty() ? std::move(note)
                                      : "the film is that of this domain, not of the contact: " +
                                            none.substr(2));
  }
  r.Hc_moes_nvm = nvm_central_film(cfg.M, cfg.L, cfg.D);
  r.nvm_deviation = hertz_to_moes_film(r.Hc, cfg.M) / r.Hc_moes_nvm - 1.0;
  // A film that depends on the domain is far from the formula for that reason.
  if (std::string note = formula_note(cfg, r.nvm_deviation);
      cfg.elastic && r.warnings.empty() && !note.empty())
    r.warnings.push_back(std::move(note));
  return r;
}

double edge_load_share(const Grid2D& grid, const Field& P) {
  const double total = full_interior_sum(grid, [&](int i, int j) { return P(i, j); });
  const double edge = edge_band_sum(grid, P, {.x_min = true, .x_max = false});
  return total > 0.0 ? edge / total : 0.0;
}

RollingProblem::RollingProblem(const RollingConfig& config)
    : impl_(std::make_unique<Impl>(config)) {}
RollingProblem::~RollingProblem() = default;

namespace {
/// A rigid contact's pressure zone is about sqrt(2 Hc) wide (the gap doubles
/// there); below this many meshes of the finest grid the discrete force
/// cannot balance the load at any H0 and H0 falls towards zero (M = 100,
/// L = 0 on 257^2: 0.7 meshes).  M = 10, L = 0 converges with 6 on 129^2.
constexpr double kRigidMinMeshes = 3.0;

/// Outside a dry Hertzian contact the gap grows as (R - 1)^(3/2), so an elastic
/// film's inlet and outlet zones, where the gap is of the order of the film,
/// are about Hc^(2/3) wide.  Below one mesh there the iteration fails (a
/// negative film, or the force balance or the iteration diverging) and a
/// second deformation update cannot help; the films that converge span about
/// 1.5 meshes or more (M = 1000, L = 0 on 257^2 and L = 5 on 129^2; random
/// cases with M from 100 to 1e7, docs/validation.md, "Random cases").
constexpr double kElasticMinMeshes = 1.0;
/// The meshes that the hint asks for at least: a little more than the finest
/// films converged have (19 of 21 random films with 2 or more converged).
constexpr double kElasticHintMeshes = 2.0;

/// The zone of the formula's film that the finest grid must resolve, by body.
struct FilmZone {
  double hc;           ///< the formula's central film (rigid or elastic)
  double width;        ///< the zone's width
  double min_meshes;   ///< below this many meshes across it no run converged
  double hint_meshes;  ///< the meshes across it that the hint asks for
  const char* name;    ///< the zone and its width's measure, for messages
};

FilmZone film_zone(const RollingConfig& c) {
  const double hc = formula_central_film(c);
  if (c.elastic)
    return {hc, std::pow(hc, 2.0 / 3.0), kElasticMinMeshes, kElasticHintMeshes,
            "the inlet and outlet zones about Hc^(2/3)"};
  return {hc, std::sqrt(2.0 * hc), kRigidMinMeshes, kRigidMinMeshes,
          "the pressure zone about sqrt(2 Hc)"};
}

/// The advice of a film below the grid's resolution that needs `points` per
/// side on this domain: more points, or where more than kMaxGridPoints, that no
/// grid on a domain that holds the contact resolves it (`domain_said`: the
/// message says already that the domain is too small) or a smaller domain.
std::string more_points_text(double points, double hint_meshes, bool domain_said) {
  if (points > kMaxGridPoints)
    return fmt::format(
        "it needs about {:.2g} points per side for {:g} meshes there, more than the {} allowed: {}",
        points, hint_meshes, kMaxGridPoints,
        domain_said ? "no grid resolves it on a domain that holds the contact"
                    : "only a smaller domain that still holds the contact may resolve it");
  int grid_points = kMinGridPoints;  // the next size the grid takes, 2^k + 1
  while (grid_points < points) grid_points = 2 * grid_points - 1;
  return fmt::format("use more points (grid.points = {} or more, for {:g} meshes there){}",
                     grid_points, hint_meshes, domain_said ? "" : " or a smaller domain");
}

/// Why a run failed when its film is below the grid's resolution (fewer
/// meshes across its FilmZone than min_meshes), else "".  `domain_said`: the
/// message says already that the domain is too small, so a smaller one is not
/// offered in place of more points.
std::string resolution_hint(const RollingConfig& c, double mesh, bool domain_said) {
  const FilmZone zone = film_zone(c);
  const double meshes = zone.width / mesh;
  if (!(meshes < zone.min_meshes)) return {};
  const double points = (c.x_max - c.x_min) * zone.hint_meshes / zone.width + 1.0;
  // case.D = 1e295 gave a rigid Hc of 0, and "use at least inf points".
  if (!std::isfinite(points))
    return fmt::format(
        "; the {}formula's film Hc = {:.3g} at D = {:.3g} makes {} = {:.3g} wide: no grid "
        "resolves it",
        c.elastic ? "" : "rigid ", zone.hc, c.D, zone.name, zone.width);
  return fmt::format(
      "; the {}formula's film Hc = {:.3g} makes {} = {:.3g} wide, {:.2g} meshes: the grid cannot "
      "resolve this film: {}",
      c.elastic ? "" : "rigid ", zone.hc, zone.name, zone.width, meshes,
      more_points_text(points, zone.hint_meshes, domain_said));
}

/// The pressure zone of a rigid contact by the formula's film: the gap is
/// Hc + (X^2 + D Y^2) / 2, so the zone extends about sqrt(2 Hc) upstream (X)
/// and sqrt(2 Hc / D) to either side (Y).
struct RigidZone {
  double hc;
  double upstream;
  double aside;
  /// The points per side of the smallest domain that holds the zone, for
  /// kRigidMinMeshes across sqrt(2 Hc): above kMaxGridPoints (D below about
  /// 2e-6) no grid both holds and resolves it.
  [[nodiscard]] double holding_points() const {
    return std::max(upstream, 2.0 * aside) * kRigidMinMeshes / upstream + 1.0;
  }
  /// Whether it passes the inlet edge of the domain of `c`, or its side edges.
  [[nodiscard]] bool past_inlet(const RollingConfig& c) const { return upstream > -c.x_min; }
  [[nodiscard]] bool past_sides(const RollingConfig& c) const {
    return aside > std::min(-c.y_min, c.y_max);
  }
};

RigidZone rigid_zone(const RollingConfig& c) {
  const double hc = formula_central_film(c);
  const double upstream = std::sqrt(2.0 * hc);
  return {hc, upstream, upstream / std::sqrt(c.D)};  // 2 Hc / D overflows at D = 1e-295
}

/// Why a rigid run failed when the formula's pressure zone reaches beyond the
/// domain, else "": at case.D = 1e-150 the formula's Hc is 5e146 (M = 100)
/// and the iteration diverged with no word of why.  `film_said`: the message
/// states the formula's film already; `domain_said`: it says to extend the
/// domain already.
std::string rigid_zone_hint(const RollingConfig& c, bool film_said, bool domain_said) {
  const RigidZone zone = rigid_zone(c);
  std::vector<std::string> edges, keys;
  if (zone.past_inlet(c)) {
    edges.push_back(fmt::format("the inlet edge X = {:g}", c.x_min));
    keys.emplace_back("grid.x_min");
  }
  if (zone.past_sides(c)) {
    edges.push_back(fmt::format("the side edges Y = {:g}, {:g}", c.y_min, c.y_max));
    keys.insert(keys.end(), {"grid.y_min", "grid.y_max"});
  }
  if (edges.empty()) return {};
  const std::string film =
      film_said ? "; its pressure zone extends"
                : fmt::format(
                      "; the rigid formula's film Hc = {:.3g} at D = {:.3g} makes the "
                      "pressure zone extend",
                      zone.hc, c.D);
  return fmt::format(
      "{} about sqrt(2 Hc) = {:.3g} upstream (X) and sqrt(2 Hc / D) = {:.3g} to "
      "either side (Y), beyond {}{}",
      film, zone.upstream, zone.aside, fmt::join(edges, " and "),
      domain_said ? "" : fmt::format(": extend the domain ({})", fmt::join(keys, ", ")));
}

/// Why no grid resolves a rigid contact, else "": a formula's film beyond a
/// double (M = 1e-10, D = 1e-295), or a zone no domain of kMaxGridPoints both
/// holds and resolves (extending the domain as the zone hint asked led to
/// "use more points").
std::string unresolvable_rigid_hint(const RollingConfig& c) {
  const RigidZone zone = rigid_zone(c);
  if (!std::isfinite(zone.hc) || !std::isfinite(zone.aside))
    return fmt::format(
        "; the rigid formula's film at M = {:.3g}, D = {:.3g} is beyond the range of a double: no "
        "domain holds its pressure zone",
        c.M, c.D);
  if (!(zone.holding_points() > kMaxGridPoints)) return {};
  return fmt::format(
      "; the rigid formula's film Hc = {:.3g} at D = {:.3g} makes the pressure zone extend about "
      "sqrt(2 Hc) = {:.3g} upstream (X) and sqrt(2 Hc / D) = {:.3g} to either side (Y): a domain "
      "that holds it needs about {:.2g} points per side for {:g} meshes across sqrt(2 Hc), more "
      "than the {} allowed: no grid resolves this contact",
      zone.hc, c.D, zone.upstream, zone.aside, zone.holding_points(), kRigidMinMeshes,
      kMaxGridPoints);
}

/// Why a rigid run that some grid can resolve (unresolvable_rigid_hint is
/// empty) failed, for its message: its film unresolved or beyond the domain
/// (rigid_zone_hint), or a pressure-dependent viscosity whose steady
/// film does not exist above a bound on alpha_bar (docs/validation.md, "Rigid bodies"; the bounds
/// quoted are 0.43 at M = 10 from 129^2 to 1025^2 and 0.082 at M = 20 on 1025^2, from the
/// isoviscous rigid film: alpha_bar_max = P_max^2 J^3 / F^3 with J the integral of -ln(1 - P /
/// P_max) and F the load).
std::string rigid_hint(const RollingConfig& c, double mesh, bool domain_said) {
  const RigidZone zone = rigid_zone(c);
  const bool beyond_domain = zone.past_inlet(c) || zone.past_sides(c);
  const std::string unresolved = resolution_hint(c, mesh, domain_said || beyond_domain);
  const std::string beyond = rigid_zone_hint(c, !unresolved.empty(), domain_said);
  if (!unresolved.empty() || !beyond.empty()) return unresolved + beyond;
  if (c.L > 0.0)
    return fmt::format(
        "; rigid bodies with a pressure-dependent viscosity have a steady film only below a bound "
        "on alpha_bar: the reduced pressure (1 - exp(-alpha_bar P)) / alpha_bar of Barus' law "
        "obeys the isoviscous equation and cannot exceed 1 / alpha_bar (the bound is about 0.43 "
        "at M = 10 and 0.08 at M = 20 on the default domain; here alpha_bar = {:.3g}; "
        "docs/validation.md)",
        c.alpha_bar);
  return {};
}

/// How the relaxation updates the deformation, for messages.
std::string update_text(bool each_colour) {
  return each_colour ? "before each colour of the relaxation" : "once per sweep";
}

/// The finest-grid cycles over which a run out of cycles is judged to have
/// stalled: its measure max(residual, |force error|) fell by less than
/// kStalledRunFactor over them.  solver.tolerance = 1e-300 on 33^2 sat at a
/// residual of 2.7e-16 (round-off), solver.h0_relaxation = 1e-300 at a force
/// error of -0.103, and both were told that more cycles may converge them.
constexpr int kStalledRunCycles = 20;
constexpr double kStalledRunFactor = 0.5;

/// The measure a run out of cycles is judged by.
double stall_measure(const RollingCycle& c) {
  return std::max(c.residual, std::abs(c.force_error));
}

/// The last kStalledRunCycles cycles of the last attempt on the finest grid
/// of `history`, or nothing when it has fewer, or when the attempt is too
/// young to judge (its first cycles are the iteration's start: with
/// solver.max_cycles = 21, a run that converges with more was "stalled").
std::optional<std::pair<const RollingCycle*, const RollingCycle*>> last_window(
    const std::vector<RollingCycle>& history) {
  constexpr int kYoungestJudged = 2 * kStalledRunCycles;
  if (history.size() <= kStalledRunCycles || history.back().cycle < kYoungestJudged)
    return std::nullopt;
  const RollingCycle& last = history.back();
  const RollingCycle& before = history[history.size() - 1 - kStalledRunCycles];
  if (before.points != last.points || before.attempt != last.attempt) return std::nullopt;
  return std::pair{&before, &last};
}

/// The mean factor per cycle by which the measure fell over the last window
/// when every cycle of it lowered the measure (slow but steady: a small
/// solver.h0_relaxation takes about 1 % of the force error per cycle, and was
/// told that more cycles would not converge it), else nothing.
std::optional<double> steady_rate(const std::vector<RollingCycle>& history) {
  const auto window = last_window(history);
  if (!window) return std::nullopt;
  const std::size_t end = history.size();
  for (std::size_t i = end - kStalledRunCycles; i < end; ++i)
    if (!(stall_measure(history[i]) < stall_measure(history[i - 1]))) return std::nullopt;
  return std::pow(stall_measure(*window->second) / stall_measure(*window->first),
                  1.0 / kStalledRunCycles);
}

/// True when the last attempt on the finest grid of `history` stalled.
bool stalled(const std::vector<RollingCycle>& history) {
  const auto window = last_window(history);
  return window &&
         !(stall_measure(*window->second) < kStalledRunFactor * stall_measure(*window->first));
}

/// A run still converging steadily is told that more cycles may converge it
/// when its rate would reach the tolerance within this many times
/// solver.max_cycles more: a Newton step of H0 of 1e-9 lowered the force
/// error by 1e-9 per cycle, steadily, and was told so ("by 1 per cycle").
constexpr double kPromisingCyclesFactor = 10.0;
/// The cycles said to be needed are the steady rate's times this: its rate
/// slows near the tolerance (solver.h0_relaxation = 0.02 on 33^2 was told 342
/// more after 120 and needed 348; 0.03 after 50, 237 and 256).
constexpr double kMoreCyclesMargin = 1.25;

/// A steady rate of `history`'s last window, and the cycles the last
/// cycle's measure needs to reach `tolerance` at it.
struct SteadyProgress {
  double rate = 1.0;
  double more_cycles = 0.0;
};
std::optional<SteadyProgress> steady_progress(const std::vector<RollingCycle>& history,
                                              double tolerance) {
  const std::optional<double> rate = steady_rate(history);
  if (!rate || !(*rate < 1.0)) return std::nullopt;
  return SteadyProgress{*rate,
                        std::log(tolerance / stall_measure(history.back())) / std::log(*rate)};
}

std::string round_off_text(const RollingConfig& c, const RollingCycle& last) {
  return fmt::format(
      "; its max(residual, |force error|), {:.2g}, is at round-off: solver.tolerance = {:g} is "
      "below what it can reach",
      stall_measure(last), c.tolerance);
}

/// What the last cycles of a run out of cycles tell, or "": at round-off,
/// still converging (at what rate, how many more cycles), or stalled.
std::string progress_hint(const RollingConfig& c, const std::vector<RollingCycle>& history) {
  if (!history.empty() && stall_measure(history.back()) < kRoundOffResidual)
    return round_off_text(c, history.back());
  if (const std::optional<SteadyProgress> steady = steady_progress(history, c.tolerance)) {
    const double needed = std::ceil(kMoreCyclesMargin * steady->more_cycles);
    const std::string converging = fmt::format(
        "; it was still converging, slowly (max(residual, |force error|) fell in each of its last "
        "{} cycles, by {:.2g} % of it per cycle)",
        kStalledRunCycles, 100.0 * (1.0 - steady->rate));
    if (steady->more_cycles <= kPromisingCyclesFactor * c.max_cycles)
      return converging + fmt::format(
                              ": about {:.0f} more cycles may reach solver.tolerance (raise "
                              "solver.max_cycles to {:.0f})",
                              needed, needed + c.max_cycles);
    return converging + fmt::format(
                            ", so slowly that it would need about {:.3g} more cycles: does a "
                            "solver.* setting (such as solver.h0_relaxation) hold it?",
                            needed);
  }
  if (stalled(history))
    return fmt::format(
        "; it stalled (max(residual, |force error|) fell by less than {:g} times in its last {} "
        "cycles): more cycles will not converge it; does a solver.* setting (such as "
        "solver.h0_relaxation), or an extreme parameter, hold it?",
        1.0 / kStalledRunFactor, kStalledRunCycles);
  return {};
}

/// The largest L at which every elastic contact of the grid M in {2, 5, 10,
/// 38, 100, 300, 1000} x L in {10, 25, 50, 75, 100, 150} on 65^2 converged
/// (or had a negative film that more points resolve).  The first failures:
/// L = 75 at M = 2, L = 100 at M = 5 and 38, L = 150 at M = 10, 100 and 300;
/// every M but 1000 failed at L = 150.  The three tried on 129^2 and 257^2
/// failed there too, with either deformation update (docs/validation.md,
/// "Beyond L = 50").
constexpr double kLargestConvergedL = 50.0;

/// Why an elastic contact above kLargestConvergedL failed, else "": half the
/// Newton step of H0 converged two of seven failures on 65^2 (M = 5 and 38 at
/// L = 100), a tenth of it one.
std::string beyond_converged_L_hint(const RollingConfig& c) {
  if (!c.elastic || !(c.L > kLargestConvergedL)) return {};
  return fmt::format(
      "; L = {:.4g} lies beyond the range the rolling solver converges (every M from 2 to 1000 "
      "up to L = {:g}; above it some fail on every grid and with either deformation update; "
      "\"Beyond L = 50\" in docs/validation.md): solver.h0_relaxation = 0.5 may converge it "
      "(two of seven such failures on 65^2), but no setting is known that converges them all",
      c.L, kLargestConvergedL);
}

/// What else to try when an elastic contact's iteration ran out of cycles
/// (not when its domain is the reason): the other deformation update, unless
/// the run has tried it (RollingConfig::fallback_update says why); or that
/// more cycles will not help, when the run stalled (`history`).
std::string relaxation_hint(const RollingConfig& c, bool other_update_tried,
                            const std::vector<RollingCycle>& history) {
  if (std::string progress = progress_hint(c, history); !progress.empty()) return progress;
  if (other_update_tried) return "; more cycles (solver.max_cycles) may converge it";
  const bool each_colour = c.relaxation.deformation_each_colour;
  return fmt::format(
      "; more cycles (solver.max_cycles), or the deformation updated {} (--set "
      "solver.deformation_updates={}: at L = 20 on 1025^2 each of the two converges a case the "
      "other does not), may converge it",
      update_text(!each_colour), reynolds::deformation_updates_text(!each_colour));
}

/// What to try after an elastic failure that the film's resolution does not
/// explain: for an L beyond the converged range, that; else, when the run
/// ran out of cycles and its domain is not the reason, the relaxation's hint.
std::string elastic_hint(const RollingConfig& c, bool domain_explains, bool out_of_cycles,
                         bool other_update_tried, const std::vector<RollingCycle>& history) {
  if (std::string beyond = beyond_converged_L_hint(c); !beyond.empty()) return beyond;
  if (domain_explains || !out_of_cycles) return {};
  return relaxation_hint(c, other_update_tried, history);
}
}  // namespace

RollingResult RollingProblem::run(const CycleMonitor& monitor, const FallbackMonitor& on_fallback) {
  std::string first_failure;
  try {
    return solve(monitor);
  } catch (const AtRoundOff&) {
    throw;  // complete as it is: no other update gets below round-off
  } catch (const RollingFailure& e) {
    const RollingConfig& c = impl_->cfg;
    const std::string domain = impl_->domain_hint();
    const bool out_of_cycles = dynamic_cast<const CyclesExhausted*>(&e) != nullptr;
    const std::string unresolved = c.elastic && !dynamic_cast<const NegativeFilm*>(&e)
                                       ? resolution_hint(c, impl_->grid.h(), !domain.empty())
                                       : std::string();
    if (!(c.elastic && c.fallback_update && out_of_cycles && domain.empty() &&
          unresolved.empty())) {
      std::string why;
      // Where no grid resolves a rigid contact, extending the domain cannot help.
      if (std::string none = c.elastic ? std::string() : unresolvable_rigid_hint(c); !none.empty())
        throw RollingFailure(e.what() + none);
      if (!c.elastic) {
        why = rigid_hint(c, impl_->grid.h(), !domain.empty());
      } else if (!unresolved.empty()) {
        why = unresolved;
      } else {
        why = elastic_hint(c, !domain.empty(), out_of_cycles, false, impl_->history);
      }
      throw RollingFailure(e.what() + domain + why);
    }
    first_failure = e.what();
  }
  return solve_with_other_update(first_failure, monitor, on_fallback);
}

RollingResult RollingProblem::solve_with_other_update(const std::string& why,
                                                      const CycleMonitor& monitor,
                                                      const FallbackMonitor& on_fallback) {
  std::vector<RollingCycle> history = std::move(impl_->history);
  const double work = impl_->hierarchy.work_units();
  const int cycles = history.back().points == impl_->grid.n ? history.back().cycle : 0;
  RollingConfig other = impl_->cfg;
  const bool each_colour = !other.relaxation.deformation_each_colour;
  other.relaxation.deformation_each_colour = each_colour;
  impl_.reset();  // one hierarchy in memory at a time
  impl_ = std::make_unique<Impl>(other);
  if (on_fallback)
    on_fallback(fmt::format("{}; solving again from the start with the deformation updated {}", why,
                            each_colour ? "before each colour" : "once per sweep"));
  RollingResult result;
  try {
    result = solve(monitor);
  } catch (const RollingFailure& e) {
    const std::string domain = impl_->domain_hint();
    const bool out_of_cycles = dynamic_cast<const CyclesExhausted*>(&e) != nullptr;
    throw RollingFailure(
        fmt::format("{}{}, with the deformation updated {}; with it updated {} before that: {}{}",
                    e.what(), domain, update_text(each_colour), update_text(!each_colour), why,
                    elastic_hint(other, !domain.empty(), out_of_cycles, true, impl_->history)));
  }
  for (RollingCycle& c : result.history) c.work += work;
  history.insert(history.end(), result.history.begin(), result.history.end());
  result.history = std::move(history);
  result.work += work;
  result.fallback_after = cycles;
  return result;
}

RollingResult RollingProblem::solve(const CycleMonitor& monitor) {
  Impl& s = *impl_;
  const int start = s.start_level();
  s.start_from_hertz(start);
  bool converged = false;
  for (int level = start; level >= 0; --level) {
    if (level < start) s.solver->interpolate_solution(level);
    converged = s.solve_stage(level, level == 0 ? s.cfg.max_cycles : s.cfg.fmg_cycles, monitor);
  }
  if (!converged) {
    const RollingCycle& last = s.history.back();
    throw CyclesExhausted(fmt::format(
        "not converged in solver.max_cycles = {} cycles on the {}^2 grid: residual {:.3e}, "
        "force error {:.3e} (solver.tolerance = {:g})",
        s.cfg.max_cycles, last.points, last.residual, last.force_error, s.cfg.tolerance));
  }
  RollingResult result = s.result();
  if (!(result.Hm > 0.0))
    throw NegativeFilm(fmt::format(
        "the film is negative (H = {:.3g} at X = {:.4g}, Y = {:.4g}) on the {}^2 grid: the "
        "grid cannot resolve this film: use more points (grid.points)",
        result.Hm, result.X_Hm, result.Y_Hm, result.grid.n));
  return result;
}

}  // namespace ehlsim
