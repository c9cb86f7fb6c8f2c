#include "impact/RunGuards.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "dynamics/DryHertz.hpp"
#include "grid/FieldExtrema.hpp"
#include "grid/NumberText.hpp"
#include "reynolds/ReynoldsOperator.hpp"

namespace ehlsim {

namespace {
/// Relative room of the speed bound for the film's own discretisation: 2 % of
/// V0 (4 % of the energy).  The largest rebound speed of the case map
/// (docs/validation.md) is 0.998 V0, M = 10000 on 65^2.
constexpr double kSpeedTolerance = 0.02;
/// ... plus the time-discretisation error of the Newmark scheme, O(dT^2): the
/// dry Hertz impact has error constants <= 0.32 (tests/test_dynamics.cpp,
/// SecondOrderInTimeStep); 1 leaves a factor 3.
constexpr double kSpeedTimeError = 1.0;
/// Delta may not go below (1 + kApproachMargin) times the dry Hertz approach of
/// the run's energy (plus the waviness amplitude).  The dry approach is the
/// largest one for that energy: of all deformations with H >= 0 at a given
/// Delta, the Hertz contact stores the least elastic energy (the contact
/// problem is the energy minimum).  50 %: room for the grid.
constexpr double kApproachMargin = 0.5;
/// The force may not exceed this many times the largest force the run's
/// energy can hold (elastic bodies).  The elastic energy of a force F spread
/// over the domain is at least F^2 / (sqrt(2) pi b) times 3 / (4 pi) (the
/// capacity of the disc around the square domain of half-width b), and it
/// cannot exceed the run's energy: F <= sqrt(energy0 (4 pi / 3) sqrt(2) pi b).
/// On the default domain (b = 1.5) and energy that is 1.6 times the dry Hertz
/// force; the largest film force of the case map is 1.4 times the dry force
/// (M = 1, L = 5, the quasi-static film at T = 0).  A slow ball's squeeze film
/// spreads its force wider than the Hertz contact: at V0 = 1e-6, Delta0 = 0.01
/// (33^2) the force of the first step is 0.31 times this bound and 6.4 times
/// the dry force (the dry bound ended that run as diverged).  2 leaves room for the grid.
constexpr double kForceMargin = 2.0;
/// A step that no attempt brought below solver.tolerance is kept when its
/// residual is at most this many times the tolerance, and counted in
/// unconverged_steps; worse, the run ends.  The case map's legitimate runs
/// kept steps at up to 25 times the tolerance (65^2, M = 10, L = 20); the
/// degenerate Roelands z = 1e6 case stays 300 to 1000 times above it.
constexpr double kMaxKeptResidualFactor = 100.0;
/// At rest: at most this fraction of the impact energy V0^2 / 2 is left in the
/// ball and the solids, so that any later rebound is below 1 % of V0.
constexpr double kRestEnergyFraction = 1e-4;
/// time.max_steps default: the steps of this many dry lift-off times.  The
/// case map's runs end by 1.03 dry lift-off times (Roelands-DH M = 1000, T = 4.31).
constexpr double kMaxStepsDryLiftOffs = 4.0;

std::string where(const StepRecord& r) { return time_step_text(r.step, r.T); }
}  // namespace

std::string time_step_text(int step, double T) {
  constexpr double kShownByDecimals = 1e-3;  // five decimals show it to two digits or more
  return T == 0.0 || std::abs(T) >= kShownByDecimals
             ? fmt::format("time step {} (T = {:.5f})", step, T)
             : fmt::format("time step {} (T = {:.4g})", step, T);
}

double waviness_height(const ImpactConfig& c, double x, double y) {
  return reynolds::Waviness{c.waviness_amplitude, c.waviness_wavelength, c.waviness_angle_deg}
      .height(x, y);
}

double elastic_energy(const Grid2D& grid, const Field& P, const Field& W) {
  const double sum = full_interior_sum(grid, [&](int i, int j) { return P(i, j) * W(i, j); });
  return 3.0 / (4.0 * std::numbers::pi) * sum * grid.h() * grid.h();
}

double default_max_steps_exact(double Delta0, double V0, double dT) {
  const double dry_lift_off = Delta0 / V0 + dry_contact_duration(V0);
  return std::ceil(kMaxStepsDryLiftOffs * dry_lift_off / dT);
}

int default_max_steps(double Delta0, double V0, double dT) {
  // Saturated: a start too far or too slow for an int is refused as input
  // (config/Parameters.cpp, kMaxTimeSteps), never cast out of range.
  const double steps = default_max_steps_exact(Delta0, V0, dT);
  return steps < std::numeric_limits<int>::max() ? static_cast<int>(steps)
                                                 : std::numeric_limits<int>::max();
}

namespace {
/// A rigid ball in a piezoviscous film keeps no step above solver.tolerance.
/// Its film pressure has no bounded solution once the ball is close enough
/// at its speed (the rigid Barus film, model.md), and the steps no attempt
/// converged there were no film: M = 37.77, L = 11, Delta0 = 0.631, V0 =
/// 0.481 on 129^2 had p_center 0.11, 0.22 and 0.36 at steps 20, 24 and 25 as
/// the ball closed in, then kept 19 steps of the next 19 above the tolerance
/// (exit 0 at T_end), p_max jumping between 0.1 and 0.38, and between 0.24 and
/// 1.76 with other time steps.
bool keeps_no_unconverged_step(const ImpactConfig& c) {
  // A Roelands law with z = 0 is isoviscous (it was told to use a smaller L).
  const bool piezoviscous = c.lubricant.viscosity == ViscosityModel::Roelands
                                ? c.lubricant.roelands_z > 0.0
                                : c.alpha_bar > 0.0;
  return !c.elastic && piezoviscous;
}

/// A rigid ball moving away from the flat faster than this times V0 has
/// rebounded: the speed of the energy left at rest (kRestEnergyFraction).
constexpr double kRigidReboundSpeed = 0.01;
}  // namespace

RunBounds run_bounds(const ImpactConfig& c, double dT, double elastic_energy0) {
  RunBounds b;
  b.energy0 = 0.5 * c.V0 * c.V0 + std::max(0.0, elastic_energy0);
  b.max_speed = std::sqrt(2.0 * b.energy0) * (1.0 + kSpeedTolerance + kSpeedTimeError * dT * dT);
  const double approach = dry_largest_approach(b.energy0);
  b.min_delta = -(1.0 + kApproachMargin) * (approach + c.waviness_amplitude);
  if (c.elastic)
    b.max_force = kForceMargin * std::sqrt(b.energy0 * 4.0 * std::numbers::pi / 3.0 *
                                           std::numbers::sqrt2 * std::numbers::pi * c.half_width);
  b.max_residual = (keeps_no_unconverged_step(c) ? 1.0 : kMaxKeptResidualFactor) * c.tolerance;
  b.rest_energy = kRestEnergyFraction * 0.5 * c.V0 * c.V0;
  b.dT = dT;
  return b;
}

FilmMinimum film_minimum(const Grid2D& grid, const Field& P, const Field& H) {
  const PointValue m = interior_minimum(grid, H);
  return {m.value, m.x, m.y, P(m.i, m.j)};
}

void check_step_physics(const StepRecord& r, const RunBounds& b, const ImpactConfig& c,
                        const FilmMinimum& film) {
  for (const double v : {r.Delta, r.dDelta_dT, r.force, r.h_min, r.p_max, r.residual}) {
    if (!std::isfinite(v))
      throw RunFailure(fmt::format(
          "{}: the state is not finite (Delta = {}, dDelta/dT = {}, force = {}, h_min = {}, "
          "p_max = {}): the solution diverged",
          where(r), r.Delta, r.dDelta_dT, r.force, r.h_min, r.p_max));
  }
  if (r.residual > b.max_residual && keeps_no_unconverged_step(c))
    throw RunFailure(fmt::format(
        "{}: no attempt converged (residual {:.3g}, above solver.tolerance = {:g}; Delta = {:.4g}, "
        "dDelta/dT = {:.4g}): a rigid ball in a piezoviscous film, whose pressure has no bounded "
        "solution once the ball is this close at this speed; use body.elastic = true, a smaller "
        "L or a slower ball",
        where(r), r.residual, c.tolerance, r.Delta, r.dDelta_dT));
  if (r.residual > b.max_residual)
    throw RunFailure(fmt::format(
        "{}: no attempt converged (residual {:.3g}, more than {:g} times solver.tolerance = {:g}): "
        "the multigrid solver cannot solve this step, its film is not trusted{}",
        where(r), r.residual, b.max_residual / c.tolerance, c.tolerance, rigid_film_hint(c)));
  // A rigid ball has no elastic energy to give back: its film only brakes
  // it.  M = 20, L = 0 on 33^2 "lifted off" at 0.37 V0 after a halved step
  // (0.17 on 65^2, 0.06 on 129^2); with time.dT = 0.02 or 0.005 on 33^2 its
  // film went negative instead: the film is thinner than the grid resolves.
  if (!c.elastic && r.dDelta_dT > kRigidReboundSpeed * c.V0)
    throw RunFailure(fmt::format(
        "{}: the rigid ball moves away from the flat (dDelta/dT = {:.4g}): with no elastic energy "
        "to give back, a rigid ball in a film cannot rebound; the grid and the time step cannot "
        "resolve this film: use more points (grid.points = {}) or a shorter time step (time.dT = "
        "{:.4g})",
        where(r), r.dDelta_dT, c.grid_points, b.dT));
  if (std::abs(r.dDelta_dT) > b.max_speed)
    throw RunFailure(fmt::format(
        "{}: the ball speed |dDelta/dT| = {:.4g} exceeds {:.4g}, the most the energy of the "
        "impact allows (no energy source): the solution diverged",
        where(r), std::abs(r.dDelta_dT), b.max_speed));
  if (r.Delta < b.min_delta || r.force > b.max_force)
    throw RunFailure(fmt::format(
        "{}: Delta = {:.4g}, force = {:.4g} beyond the bounds of the impact energy (Delta >= "
        "{:.4g}, force <= {:.4g}): the solution diverged",
        where(r), r.Delta, r.force, b.min_delta, b.max_force));
  if (film.h < 0.0) {
    // A time step longer than the mesh (time.dT given) shares the blame.
    const double mesh = Grid2D(c.grid_points, c.half_width).h();
    const std::string long_step =
        c.dT > mesh
            ? fmt::format(", or a shorter time step (time.dT = {:g}, the mesh {:.4g})", c.dT, mesh)
            : std::string();
    throw RunFailure(fmt::format(
        "{}: negative film h_min = {:.3g} at X = {:.4g}, Y = {:.4g} (P = {:.3g} there): the "
        "surfaces pass through each other; the grid cannot resolve this film: use more points "
        "(grid.points = {}){}",
        where(r), film.h, film.x, film.y, film.p, c.grid_points, long_step));
  }
}

double steady_fall_rate(const std::vector<double>& residuals) {
  const std::size_t n = residuals.size();
  if (n < 2) return 1.0;
  const std::size_t cycles = std::min<std::size_t>(n - 1, kInitialRateCycles);
  const std::size_t first = n - 1 - cycles;
  for (std::size_t i = first; i + 1 < n; ++i) {
    if (!std::isfinite(residuals[i]) || !(residuals[i + 1] < residuals[i])) return 1.0;
  }
  return std::pow(residuals.back() / residuals[first], 1.0 / static_cast<double>(cycles));
}

double round_off_residual(double max_pressure, int points) {
  const double n = static_cast<double>(points);
  return kRoundOffUlps * std::numeric_limits<double>::epsilon() * max_pressure / std::sqrt(n);
}

bool stalled_at_round_off(const std::vector<double>& residuals,
                          const std::function<double()>& floor) {
  constexpr std::size_t kWindow = kRoundOffCycles + 1;
  if (residuals.size() < kWindow) return false;
  const auto window = std::span(residuals).last(kWindow);
  if (window.back() < 0.5 * window.front()) return false;  // still falling
  const double below = floor();
  return std::ranges::all_of(window, [&](double r) { return r < below; });
}

std::string round_off_text(double residual, double tolerance) {
  return fmt::format(
      "stopped converging at a residual of {:.3g}, the round-off of its pressure (it fell by less "
      "than half in its last {} cycles): solver.tolerance = {:g} is below what it can reach; "
      "raise solver.tolerance",
      residual, kRoundOffCycles, tolerance);
}

void check_initial_state(const InitialSolve& s, const ImpactConfig& c) {
  const double force = s.force, residual = s.residual;
  if (std::isfinite(force) && std::isfinite(residual) && residual <= c.tolerance) return;
  if (s.at_round_off) {
    throw RunFailure(fmt::format("time step 0 (T = 0): the film pressure at time.Delta0 = {:g} {}",
                                 c.Delta0, round_off_text(residual, c.tolerance)));
  }
  // Falling, below its start, and with a force the impact's energy can hold:
  // a start that overflowed falls fast from far above any film (M = 0.53,
  // L = 21.2, Delta0 = 1.04 on 129^2: residual 8e29 falling by 0.02 per
  // cycle, then 7e60 with 40 cycles, not finite with 80).
  const bool converging = s.rate <= kStillConvergingRate && residual < s.first_residual &&
                          std::abs(force) <= run_bounds(c, 0.0, 0.0).max_force;
  if (std::isfinite(force) && std::isfinite(residual) && converging) {
    throw RunFailure(fmt::format(
        "time step 0 (T = 0): the film pressure at time.Delta0 = {:g} was still converging "
        "when solver.max_cycles = {} ran out (residual {:.3g}, falling by {:.2f} per cycle, "
        "towards solver.tolerance = {:g}): raise solver.max_cycles or solver.tolerance",
        c.Delta0, c.max_cycles, residual, s.rate, c.tolerance));
  }
  const std::string state = fmt::format(
      "time step 0 (T = 0): the film pressure at time.Delta0 = {:g} did not converge "
      "(residual {}, force {})",
      c.Delta0, finite_or_text(residual, "{:.3g}"), finite_or_text(force, "{:.3g}"));
  // A film without a bounded pressure is blamed only where one may be missing:
  // a Roelands film, or a Barus film closer than the rigid estimate allows.
  const double estimate = c.alpha_bar * c.lambda_bar * c.V0 / 4.0;
  const bool barus = c.lubricant.viscosity == ViscosityModel::Barus;
  if (!barus || c.Delta0 * c.Delta0 <= estimate) {
    const std::string why = barus
                                ? fmt::format(
                                      " (rigid Barus film: the pressure diverges unless Delta0^2 > "
                                      "alpha_bar lambda_bar V0 / 4 = {:.3g})",
                                      estimate)
                                : std::string();
    throw RunFailure(fmt::format(
        "{}: the film is too viscous for the ball to arrive there at time.V0 = {:g}{}; start "
        "further away (a larger time.Delta0)",
        state, c.V0, why));
  }
  const std::string bounded =
      c.alpha_bar > 0.0
          ? fmt::format(
                "the rigid Barus estimate (Delta0^2 = {:.3g} > alpha_bar lambda_bar V0 / 4 "
                "= {:.3g}) says its pressure is bounded",
                c.Delta0 * c.Delta0, estimate)
          : std::string("an isoviscous film has a bounded pressure at any start");
  throw RunFailure(fmt::format(
      "{} in solver.max_cycles = {} cycles, although {}: the solver did not converge it; raise "
      "solver.max_cycles, or check the solver's settings (solver.*) and the grid",
      state, c.max_cycles, bounded));
}

void check_step_cap(const StepRecord& r, const ImpactConfig& c, double dT) {
  if (std::isfinite(c.T_end)) return;  // a run to T_end has its own end
  const int cap = c.max_steps > 0 ? c.max_steps : default_max_steps(c.Delta0, c.V0, dT);
  if (r.step < cap) return;
  throw RunFailure(fmt::format(
      "{}: no lift-off after {} steps (time.max_steps; Delta = {:.4g}, dDelta/dT = {:.4g}, "
      "p_max = {:.4g}): raise time.max_steps, or set time.T_end to stop at a given time",
      where(r), r.step, r.Delta, r.dDelta_dT, r.p_max));
}

std::string rigid_film_hint(const ImpactConfig& c) {
  if (c.elastic) return {};
  return "; a rigid ball's film thins without bound as it closes in, below what the grid "
         "resolves: use more points, or body.elastic = true";
}

std::string domain_note(double edge_impulse, const ImpactConfig& c) {
  const double share = edge_impulse / c.V0;
  if (!(share > kEdgeImpulseWarning)) return {};
  // Twice the half-width on 2 (n - 1) + 1 points keeps the mesh (and a
  // grid of 2^k + 1 points).
  return fmt::format(
      "the film within a tenth of the side from the domain's edges took {:.1f} % of the impact "
      "momentum (more than {:g} %): the boundary condition P = 0 there cuts the squeeze film "
      "short, and the results depend on the domain; widen it at the same mesh (grid.half_width "
      "= {:g} with grid.points = {} doubles it) and compare",
      100.0 * share, 100.0 * kEdgeImpulseWarning, 2.0 * c.half_width, 2 * c.grid_points - 1);
}

std::string spike_note(double waviness_amplitude) {
  if (!(waviness_amplitude > 0.0)) return {};
  return fmt::format(
      "the waviness (surface.waviness_amplitude = {:g}) makes the pressure depend on the "
      "direction, while the spike analysis (spike.csv, ehlsim spike) sorts the pressure of "
      "X, Y >= 0 by the radius R alone: its R_s and P_s are of that mixture of directions; "
      "axis_profiles.csv (ehlsim spike) and fields.nc hold the pressure itself",
      waviness_amplitude);
}

std::string start_note(double initial_elastic_energy, const ImpactConfig& c) {
  const double share = initial_elastic_energy / (0.5 * c.V0 * c.V0);
  if (!(share > kStartEnergyWarning)) return {};
  return fmt::format(
      "the film at T = 0 stores {:.3g} times the impact energy V0^2 / 2 in the solids (more "
      "than {:g} %): the ball is already braking at time.Delta0 = {:g}, and its rebound can take "
      "that energy back (a rebound speed up to {:.3g} V0); start further away (a larger "
      "time.Delta0) for the impact of a free ball at time.V0",
      share, 100.0 * kStartEnergyWarning, c.Delta0, std::sqrt(1.0 + share));
}

std::vector<std::string> run_warnings(const RunSummary& s, const ImpactConfig& c) {
  std::vector<std::string> warnings;
  for (std::string note : {start_note(s.initial_elastic_energy, c), domain_note(s.edge_impulse, c),
                           spike_note(c.waviness_amplitude)})
    if (!note.empty()) warnings.push_back(std::move(note));
  return warnings;
}

bool is_at_rest(double V, double elastic_energy, const RunBounds& b) {
  return 0.5 * V * V + elastic_energy <= b.rest_energy;
}

}  // namespace ehlsim
