#pragma once
// How an impact run may end, and the physics guards checked after every step
// (docs/usage.md, "How a run ends"; docs/validation.md, "Robustness over the
// parameter range").
//
// Energy is the yardstick.  In units of m v0^2 the ball carries V^2 / 2 and
// the elastic solids (3 / (4 pi)) Int Int P W dX dY (W = H - Delta - the
// undeformed shape: the deformation).  Film and solids only dissipate, so the
// sum never grows beyond its value at T = 0 (the impact energy V0^2 / 2 plus
// the elastic energy of the quasi-static film the run starts with).  A state
// that breaks a bound derived from it did not come from the equations: the
// run ends with exit 1 and says why.
#include <functional>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "grid/Grid.hpp"
#include "impact/ImpactConfig.hpp"
#include "impact/ImpactObserver.hpp"

namespace ehlsim {

/// Height A_w cos(2 pi (X cos th + Y sin th) / wavelength) of the surface
/// waviness at (x, y) (model.md): reynolds::Waviness::height, the operator's own.
[[nodiscard]] double waviness_height(const ImpactConfig& c, double x, double y);

/// Elastic energy (3 / (4 pi)) h^2 sum P W of the solids (W the deformation,
/// zero for rigid bodies), in units of m v0^2, over the full grid that `grid`
/// stands for.
[[nodiscard]] double elastic_energy(const Grid2D& grid, const Field& P, const Field& W);

/// The default of time.max_steps: the steps of kMaxStepsDryLiftOffs times the
/// dry lift-off time Delta0 / V0 + T_c(V0) at the time step dT.
/// Saturates at the largest int; default_max_steps_exact is the unrounded count.
[[nodiscard]] int default_max_steps(double Delta0, double V0, double dT);
[[nodiscard]] double default_max_steps_exact(double Delta0, double V0, double dT);

/// "time step N (T = ...)", the start of a failed step's message: T to five
/// decimals, or to four digits when it is shorter than that shows ("T =
/// 0.00000" after five steps of time.dT = 1e-6).
[[nodiscard]] std::string time_step_text(int step, double T);

/// The bounds of one run, fixed at T = 0 from its energy.
struct RunBounds {
  double energy0 = 0.0;    ///< V0^2 / 2 + elastic energy at T = 0 [m v0^2]
  double max_speed = 0.0;  ///< |dDelta/dT| (no energy source)
  double min_delta = 0.0;  ///< Delta (the dry Hertz approach of energy0, with margin)
  double max_force = std::numeric_limits<double>::infinity();  ///< elastic bodies only
  double max_residual = 0.0;  ///< of a step kept above solver.tolerance
  double rest_energy = 0.0;   ///< below this remaining energy the ball is at rest
  double dT = 0.0;            ///< the run's time step (for messages)
};

[[nodiscard]] RunBounds run_bounds(const ImpactConfig& c, double dT, double elastic_energy0);

/// A run that cannot honestly go on: the message names the step, T and the reason.
class RunFailure : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// The film state at the point where h_min is reached (for the message).
struct FilmMinimum {
  double h = 0.0, x = 0.0, y = 0.0, p = 0.0;
};
[[nodiscard]] FilmMinimum film_minimum(const Grid2D& grid, const Field& P, const Field& H);

/// Throws RunFailure when the step's state is not finite, breaks a bound, has
/// a negative film, or was kept unconverged too far above the tolerance.
void check_step_physics(const StepRecord& r, const RunBounds& b, const ImpactConfig& c,
                        const FilmMinimum& film);

/// The quasi-static solve at T = 0 cycles towards this times solver.tolerance
/// (and at most solver.max_cycles); its pressure is a solution only if it got
/// below solver.tolerance.  At the edge of existence the stopping rule alone
/// was not enough: on 129^2, M = 1, 2, 3 and 10 at L = 20 met it with forces of
/// 0.0075, 0, 0 and 0.0003 (0.13 at M = 20), and asked for 1e-7 they stall at
/// 5.8e-4, 2.2e-4, 1.3e-4 and 2.7e-5 after 100 cycles, where the cases with a
/// solution (M = 20 at L = 20, M = 5 at L = 10, ...) reach it.
inline constexpr double kInitialToleranceFactor = 1e-2;

/// What the quasi-static solve at T = 0 ended with.
struct InitialSolve {
  double force = 0.0;
  double residual = 0.0;
  /// Factor per cycle by which the residual fell steadily over its last
  /// cycles (steady_fall_rate).
  double rate = 1.0;
  /// The residual of the full multigrid start, before the first cycle.
  double first_residual = std::numeric_limits<double>::infinity();
  /// It stopped at round-off (stalled_at_round_off) before solver.max_cycles.
  bool at_round_off = false;
};
/// The last cycles of the solve at T = 0 over which InitialSolve::rate is taken.
inline constexpr int kInitialRateCycles = 5;

/// The pressure-scaled residual measure (ReynoldsOperator::pressure_scaled_norm:
/// the RMS of residual / diagonal over `points` interior points, over
/// sqrt(points)) that round-off in a pressure of magnitude `max_pressure`
/// leaves: kRoundOffUlps units in the last place of it at every point.
/// solver.tolerance = 1e-300 on 33^2 cycled for ever at T = 0 with the
/// measure at 2e-19, 5 eps max|P| / sqrt(points), and was told to raise
/// solver.max_cycles.
[[nodiscard]] double round_off_residual(double max_pressure, int points);
inline constexpr double kRoundOffUlps = 100.0;
/// A solve (at T = 0, or a step's attempt) whose residual is below
/// round_off_residual and fell by less than half over this many cycles ends
/// the run there: no cycle, retry or shorter step gets further.
inline constexpr int kRoundOffCycles = 10;
/// Whether the last kRoundOffCycles + 1 `residuals` fell by less than half and
/// lie below `floor()`, which is asked only then: it scans the pressure, and
/// the test runs after every cycle of every step.
[[nodiscard]] bool stalled_at_round_off(const std::vector<double>& residuals,
                                        const std::function<double()>& floor);
/// What a solve that stalled at round-off with `residual` above `tolerance`
/// says after "the film pressure ...".
[[nodiscard]] std::string round_off_text(double residual, double tolerance);

/// A solve at T = 0 whose residual still fell this fast, and is below the
/// residual it started from, ran out of cycles, and did not stall.  (M = 0.01
/// on 33^2 overflows: its residual fell from far above its start to 4.6e27 in
/// the last cycles on one machine and was not finite on another.)  Between
/// the two measured kinds: the default case on 65^2 asked for
/// solver.tolerance = 1e-14 fell by 0.64 per cycle when solver.max_cycles
/// ended it (and reached 1e-14 with 200 cycles); of the
/// films with no solution, M = 10, L = 20 on 65^2 fell by 0.86 per cycle,
/// M = 2, 3 and 10 at L = 20 on 129^2 not at all.
inline constexpr double kStillConvergingRate = 0.75;

/// InitialSolve::rate of the residuals of a solve at T = 0, its last one
/// after its last cycle: the factor per cycle over the last
/// kInitialRateCycles cycles (all of them if fewer), or 1 (not falling)
/// unless each of them lowered a finite residual.  A history with an overflow
/// in it is no fall: M = 4, L = 10 on 129^2 cycles between 8e-5 and inf, and
/// the mean from an inf was 0.  With fewer cycles than kInitialRateCycles
/// (solver.max_cycles = 2) a film that has a solution (M = 20, L = 20 on 65^2)
/// was said to be too viscous for the start.
[[nodiscard]] double steady_fall_rate(const std::vector<double>& residuals);

/// Throws RunFailure when the film pressure at T = 0 is not a solution: not
/// finite, or its residual above solver.tolerance.  The reason is the
/// cycles when the residual was still falling (kStillConvergingRate) below
/// its start with a force within RunBounds::max_force, else a film too
/// viscous for the start.
void check_initial_state(const InitialSolve& s, const ImpactConfig& c);

/// Throws RunFailure when `step` reached the cap of a run until lift-off.
void check_step_cap(const StepRecord& r, const ImpactConfig& c, double dT);

/// At rest: the ball's kinetic energy and the elastic energy left in the
/// solids, the most any later rebound could get, is below rest_energy.
[[nodiscard]] bool is_at_rest(double V, double elastic_energy, const RunBounds& b);

/// The edge impulse (RunSummary::edge_impulse) above which a run warns that
/// its results depend on the domain, as a share of the impact momentum m V0.
/// On 129^2 the rebound speed fell by 3.3 (L = 0) to 8.7 (L = 20) times the
/// edge impulse of the paper's domain when the domain was doubled at the same
/// mesh (docs/validation.md, "The size of the domain"): at L = 10, M = 10, 20,
/// 50, 100 and 1000 took 0.027, 0.018, 0.0085, 0.0045 and 0.0003 and
/// rebounded 0.19, 0.11, 0.045, 0.020 and 0.001 V0 slower.  1 % flags every
/// case of L = 0, 10, 20 that moved by 0.1 V0 or more and none that moved by
/// 0.02 V0; M = 50 (0.045 V0) only at L = 0.
inline constexpr double kEdgeImpulseWarning = 0.01;

/// What an edge impulse (in m v0) says of the domain: a sentence when it
/// exceeds kEdgeImpulseWarning of m V0, else "".
[[nodiscard]] std::string domain_note(double edge_impulse, const ImpactConfig& c);

/// What a wavy surface means for the spike analysis, which treats the
/// pressure as a function of the radius alone (docs/model.md, section 10): a
/// sentence when the amplitude (surface.waviness_amplitude) is > 0, else "".
[[nodiscard]] std::string spike_note(double waviness_amplitude);

/// A run whose film at T = 0 stores more than this fraction of the impact
/// energy V0^2 / 2 in the solids warns: the ball is already braking at
/// time.Delta0, and the rebound can take that energy back (up to
/// sqrt(1.05) - 1 = 2.5 % of V0 here).  At Delta0 = 1 on 129^2: M = 10, L = 10
/// stores 1.3 %, M = 5 10.8 %, M = 2 (L = 0) 24 %; V0 = Delta0 = 1e-3 on 65^2
/// 1980 % and rebounded at 3.6 V0.
inline constexpr double kStartEnergyWarning = 0.05;

/// What to try when a rigid ball's step failed (its film thins without
/// bound as it closes in: M = 100, L = 0 on 33^2 and 65^2, M = 20 with
/// shorter time steps on 33^2), else "" (elastic bodies).
[[nodiscard]] std::string rigid_film_hint(const ImpactConfig& c);

/// What a start at time.Delta0 means for the rebound: a sentence when the
/// film at T = 0 stores more than kStartEnergyWarning of the impact energy in
/// the solids (in m v0^2, as RunSummary::initial_elastic_energy), else "".
[[nodiscard]] std::string start_note(double initial_elastic_energy, const ImpactConfig& c);

/// What a finished run should tell its user: start_note's, domain_note's and
/// spike_note's sentences, those that apply.
[[nodiscard]] std::vector<std::string> run_warnings(const RunSummary& s, const ImpactConfig& c);

}  // namespace ehlsim
