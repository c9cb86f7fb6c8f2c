// Robustness over the parameter range (issue 9, docs/validation.md): the
// energy bounds and guards of impact/RunGuards, and a coarse version of the
// case map run through the command line: every case ends in lift-off, at rest,
// or exit 1 naming the step and the reason; bad input is exit 2.
#include <gtest/gtest.h>
#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <limits>
#include <nlohmann/json.hpp>
#include <numbers>
#include <sstream>
#include <string>

#include "dynamics/DryHertz.hpp"
#include "grid/EdgeBand.hpp"
#include "impact/RunGuards.hpp"
#include "support/RunEhlsim.hpp"
#include "support/TempDir.hpp"

namespace {

namespace fs = std::filesystem;
using namespace ehlsim;
using ehlsim::testing::ehlsim;
using ehlsim::testing::quote;
using ehlsim::testing::read_file;
using ehlsim::testing::Result;
using ehlsim::testing::TempDir;

// ---------------------------------------------------------------------------
// The bounds and guards
// ---------------------------------------------------------------------------

TEST(RunGuards, ElasticEnergyOfTheDryHertzContactIsItsWork) {
  // Hertz pressure P = sqrt(1 - r^2) (A = 1, Delta = -1) with its deformation
  // W = 1 - r^2/2 inside, (1/pi)[(2 - r^2) asin(1/r) + sqrt(r^2 - 1)] outside
  // (model.md): the energy stored must be the work of the dry force on the
  // way in, Int_0^1 (-Delta)^(3/2) d(-Delta) = 2/5 (units m v0^2).
  const Grid2D grid(257, 1.5);
  Field P(grid), W(grid);
  for (int j = 0; j < grid.n; ++j) {
    for (int i = 0; i < grid.n; ++i) {
      const double r2 = grid.x(i) * grid.x(i) + grid.y(j) * grid.y(j), r = std::sqrt(r2);
      P(i, j) = r < 1.0 ? std::sqrt(1.0 - r2) : 0.0;
      W(i, j) = r <= 1.0
                    ? 1.0 - 0.5 * r2
                    : ((2.0 - r2) * std::asin(1.0 / r) + std::sqrt(r2 - 1.0)) / std::numbers::pi;
    }
  }
  EXPECT_NEAR(elastic_energy(grid, P, W), 0.4, 2e-3);
  // The same on the quadrant, where the points off the axes count twice or four times.
  const Grid2D quadrant = grid.quadrant();
  EXPECT_NEAR(elastic_energy(quadrant, fold(P, quadrant), fold(W, quadrant)),
              elastic_energy(grid, P, W), 1e-12);
}

TEST(RunGuards, BoundsFollowFromTheEnergy) {
  ImpactConfig c;
  const RunBounds b = run_bounds(c, 0.01, 0.0);
  // The dry impact with this energy reaches Delta_min = -1.09336 (model.md)
  // and the force (2 pi / 3) 1.09336^(3/2): both stay inside the bounds.
  EXPECT_LT(b.min_delta, -1.09336);
  EXPECT_GT(b.max_force, dry_hertz_force(-1.09336));
  EXPECT_GE(b.max_speed, c.V0);
  // A faster ball: the approach grows like V0^(4/5), the speed bound like V0.
  c.V0 = 2.0;
  const RunBounds fast = run_bounds(c, 0.01, 0.0);
  EXPECT_NEAR(fast.min_delta / b.min_delta, std::pow(2.0, 0.8), 1e-12);
  EXPECT_NEAR(fast.max_speed / b.max_speed, 2.0, 1e-12);
  // The force bound is the most force the energy can hold spread over the
  // domain: it grows as the root of the energy and of the domain's width.
  EXPECT_NEAR(fast.max_force / b.max_force, 2.0, 1e-12);
  c.V0 = 1.0;
  c.half_width = 4.0 * ImpactConfig{}.half_width;
  EXPECT_NEAR(run_bounds(c, 0.01, 0.0).max_force / b.max_force, 2.0, 1e-12);
  c.half_width = ImpactConfig{}.half_width;
  // Stored elastic energy at T = 0 raises the energy the bounds allow.
  EXPECT_GT(run_bounds(c, 0.01, 0.1).max_speed, b.max_speed);
  // Rigid bodies store no elastic energy: nothing bounds their viscous force.
  c.elastic = false;
  EXPECT_TRUE(std::isinf(run_bounds(c, 0.01, 0.0).max_force));
}

TEST(RunGuards, TheStepCapLeavesRoomForTheDryImpact) {
  // The default cap is several dry lift-off times at any time step.
  const DryImpact dry = simulate_dry_hertz(1.0, 1.0, 1e-3, 10.0);
  for (const double dT : {0.2, 0.05, 3.0 / 4096}) {
    EXPECT_GE(default_max_steps(1.0, 1.0, dT) * dT, 3.0 * dry.T_lift_off) << dT;
  }
}

StepRecord good_record() {
  StepRecord r;
  r.step = 7;
  r.T = 0.35;
  r.Delta = 0.5;
  r.dDelta_dT = -0.8;
  r.force = 0.5;
  r.h_min = 0.3;
  r.p_max = 0.2;
  r.residual = 1e-6;
  return r;
}

/// check_step_physics on `r` throws a RunFailure whose message holds `text`
/// and names the step and its time.
void expect_failure(const StepRecord& r, const FilmMinimum& film, const std::string& text) {
  const ImpactConfig c;
  const RunBounds b = run_bounds(c, 0.05, 0.0);
  try {
    check_step_physics(r, b, c, film);
    ADD_FAILURE() << "no failure for: " << text;
  } catch (const RunFailure& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find(text), std::string::npos) << message;
    EXPECT_EQ(message.rfind("time step 7 (T = 0.35000): ", 0), 0u) << message;
  }
}

TEST(RunGuards, EachGuardEndsTheRunWithItsReason) {
  const ImpactConfig c;
  const RunBounds b = run_bounds(c, 0.05, 0.0);
  const FilmMinimum film{0.3, 0.0, 0.0, 0.2};
  EXPECT_NO_THROW(check_step_physics(good_record(), b, c, film));
  StepRecord r = good_record();
  r.force = std::numeric_limits<double>::quiet_NaN();
  expect_failure(r, film, "the state is not finite");
  r = good_record();
  r.dDelta_dT = 1.5;
  expect_failure(r, film, "exceeds");
  r = good_record();
  r.Delta = -3.0;
  expect_failure(r, film, "beyond the bounds of the impact energy");
  r = good_record();
  r.force = 100.0;
  expect_failure(r, film, "beyond the bounds of the impact energy");
  r = good_record();
  r.residual = 1e3 * c.tolerance;
  expect_failure(r, film, "no attempt converged");
  r = good_record();
  r.h_min = -1e-4;
  expect_failure(r, {-1e-4, 0.5, 0.0, 0.1}, "negative film h_min");
}

/// The message check_initial_state throws for `s`, "" when it accepts it.
std::string initial_failure(const InitialSolve& s) {
  try {
    check_initial_state(s, ImpactConfig{});
  } catch (const RunFailure& e) {
    return e.what();
  }
  return "";
}

TEST(RunGuards, AFilmAtTZeroIsStillConvergingOnlyBelowItsStart) {
  const ImpactConfig c;
  EXPECT_EQ(initial_failure({.force = 0.01, .residual = 0.1 * c.tolerance}), "");
  // Ran out of cycles falling fast from a residual of 1: raise max_cycles.
  const std::string converging =
      initial_failure({.force = 0.01, .residual = 1e-3, .rate = 0.5, .first_residual = 1.0});
  EXPECT_NE(converging.find("was still converging"), std::string::npos) << converging;
  // Falling as fast, but from far above its start (M = 0.01 on 33^2: 4.6e27
  // after an overflow): the film has no solution at this start.
  const std::string overflowed =
      initial_failure({.force = 1e28, .residual = 4.6e27, .rate = 1e-3, .first_residual = 1.0});
  EXPECT_NE(overflowed.find("did not converge (residual 4.6e+27, force 1e+28)"), std::string::npos)
      << overflowed;
  // Falling fast below a start that had already overflowed, with a force no
  // impact can carry (M = 0.53, L = 21.2, Delta0 = 1.04 on 129^2: "raise
  // solver.max_cycles" was the advice, and 80 cycles overflowed).
  const std::string beyond_the_energy =
      initial_failure({.force = 3e29, .residual = 8.2e29, .rate = 0.02, .first_residual = 1e31});
  EXPECT_NE(beyond_the_energy.find("did not converge (residual 8.2e+29, force 3e+29)"),
            std::string::npos)
      << beyond_the_energy;
  // Not falling: no solution either.
  const std::string stalled =
      initial_failure({.force = 0.01, .residual = 1e-3, .rate = 0.95, .first_residual = 1.0});
  EXPECT_NE(stalled.find("did not converge"), std::string::npos) << stalled;
}

TEST(RunGuards, OnlyASteadyFallOfFiniteResidualsIsStillConverging) {
  // The default case on 65^2 asked for 1e-14: a steady 0.64 per cycle.
  std::vector<double> steady{1.0};
  for (int c = 0; c < 8; ++c) steady.push_back(0.64 * steady.back());
  EXPECT_NEAR(steady_fall_rate(steady), 0.64, 1e-12);
  // Fewer cycles than kInitialRateCycles (solver.max_cycles = 2): all of them.
  EXPECT_NEAR(steady_fall_rate({1.0, 0.5, 0.25}), 0.5, 1e-15);
  EXPECT_EQ(steady_fall_rate({1.0}), 1.0);
  // M = 4, L = 10 on 129^2 cycles between 8e-5 and an overflow: measured from
  // an inf five cycles back the mean fall was 0 ("falling by 0.00 per cycle").
  const double inf = std::numeric_limits<double>::infinity();
  EXPECT_EQ(steady_fall_rate({4.2e-3, 1.7e27, inf, 9.3e-5, 8.6e-5, 7.9e-5, 7.9e-5}), 1.0);
  // M = 1, L = 10 on 65^2: from 2.4e61 down to 2.0e60, then inf to the end.
  EXPECT_EQ(steady_fall_rate({1.0e84, inf, 2.4e61, 2.0e60, inf, inf, inf, inf, 7.7e30}), 1.0);
  // One cycle of the last five that did not lower it: no steady fall.
  EXPECT_EQ(steady_fall_rate({1.0, 0.5, 0.25, 0.3, 0.1, 0.05, 0.02}), 1.0);
}

TEST(RunGuards, AResidualStallsAtRoundOffOnlyBelowItsFloor) {
  // The floor of a pressure of 5.5e-3 (the default case at T = 0) on 33^2.
  const double floor = round_off_residual(5.5e-3, 31 * 31);
  const auto at = [&] { return floor; };
  EXPECT_NEAR(floor, kRoundOffUlps * 2.220446e-16 * 5.5e-3 / 31.0, 1e-24);
  std::vector<double> level(kRoundOffCycles + 1, 0.1 * floor);
  EXPECT_TRUE(stalled_at_round_off(level, at));
  // Fewer cycles than the window, or one of them above the floor: not yet.
  EXPECT_FALSE(stalled_at_round_off({level.begin() + 1, level.end()}, at));
  level.front() = 2.0 * floor;
  EXPECT_FALSE(stalled_at_round_off(level, at));
  // Still halving over the window: converging, whatever its level.
  std::vector<double> falling{0.1 * floor};
  for (int c = 0; c < kRoundOffCycles; ++c) falling.push_back(0.9 * falling.back());
  EXPECT_FALSE(stalled_at_round_off(falling, at));
  // A stall above the floor is no round-off (M = 2, L = 20 on 129^2 sat at 1e-4).
  EXPECT_FALSE(stalled_at_round_off(std::vector<double>(kRoundOffCycles + 1, 1e-4), at));
}

TEST(RunGuards, AtRestWhenTooLittleEnergyIsLeftForARebound) {
  const ImpactConfig c;
  const RunBounds b = run_bounds(c, 0.05, 0.0);
  EXPECT_TRUE(is_at_rest(0.0, 0.0, b));
  EXPECT_TRUE(is_at_rest(-0.005, 0.0, b));
  EXPECT_FALSE(is_at_rest(0.0, 0.1, b));  // the solids still push the ball back
  EXPECT_FALSE(is_at_rest(0.3, 0.0, b));  // a rebound
}

// ---------------------------------------------------------------------------
// The coarse case map through the command line
// ---------------------------------------------------------------------------

/// `ehlsim impact --quiet` on `points`^2 into dir/run with further options.
Result map_run(const TempDir& dir, int points, const std::string& options) {
  return ehlsim("impact --quiet --set grid.points=" + std::to_string(points) + " " + options +
                " --out " + quote((dir / "run").string()));
}

/// Exit 1 with one line that names the step, T and `reason`, and no output files.
void expect_failed_run(const TempDir& dir, const Result& r, const std::string& reason) {
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(r.err.rfind("ehlsim: error: time step ", 0), 0u) << r.err;
  EXPECT_NE(r.err.find("(T = "), std::string::npos) << r.err;
  EXPECT_NE(r.err.find(reason), std::string::npos) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  if (fs::exists(dir / "run")) {
    EXPECT_TRUE(fs::is_empty(dir / "run"));
  }
}

/// Exit 2 with the one line `message`, in well under a second of work.
void expect_refused_at_once(const std::string& args, const std::string& message) {
  const auto start = std::chrono::steady_clock::now();
  const Result r = ehlsim("impact --quiet " + args);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.err, "ehlsim: error: " + message + "\n");
  EXPECT_LT(seconds, 10.0);  // a loaded machine; the refusal itself takes milliseconds
}

nlohmann::json results_of(const TempDir& dir) {
  return nlohmann::json::parse(read_file(dir / "run" / "run.json")).at("results");
}

TEST(CaseMap, ProbeSmallMOnA33Grid) {
  // Used to "lift off" after 3 steps with Delta = 6.6e34: the film at T = 0
  // had not converged.  The hint (start further away) is tested below.
  TempDir dir;
  expect_failed_run(dir, map_run(dir, 33, "--set case.M=1"), "did not converge (residual");
  // An overflowing film says so in words, not with a printed NaN (its
  // residual is not finite, or astronomically large, depending on the CPU's
  // rounding: RunGuards.AFilmAtTZeroIsStillConvergingOnlyBelowItsStart).
  const Result overflow = map_run(dir, 33, "--set case.M=0.01");
  expect_failed_run(dir, overflow, "did not converge (residual ");
  EXPECT_EQ(overflow.err.find("nan"), std::string::npos) << overflow.err;
  // Its residual overflowing in the last cycles, M = 1, L = 10 on 65^2 was
  // told to raise solver.max_cycles ("falling by 0.00 per cycle").
  const Result viscous = map_run(dir, 65, "--set case.M=1 --set case.L=10");
  expect_failed_run(dir, viscous, "did not converge (residual ");
  EXPECT_NE(viscous.err.find("start further away"), std::string::npos) << viscous.err;
}

TEST(CaseMap, AFilmAtTZeroThatOnlyMeetsTheToleranceIsNoSolution) {
  // M = 10, L = 20 on 65^2 met the stopping rule at T = 0 with no force at
  // all, stalled above the tolerance when asked for less, and then "lifted
  // off" (V 0.686).  M = 20 has a film at T = 0, with a force of 0.13.
  TempDir dir;
  const Result none = map_run(dir, 65, "--set case.M=10 --set case.L=20");
  expect_failed_run(dir, none, "did not converge (residual");
  EXPECT_NE(none.err.find("too viscous"), std::string::npos) << none.err;
  // A film that is still converging when the cycles run out is no such case:
  // asked for 1e-14 the paper's case falls by 0.64 per cycle at T = 0.
  const Result tight = map_run(dir, 65, "--set solver.tolerance=1e-14");
  expect_failed_run(dir, tight,
                    "was still converging when solver.max_cycles = 20 ran out (residual ");
  EXPECT_NE(tight.err.find("raise solver.max_cycles or solver.tolerance\n"), std::string::npos)
      << tight.err;
  EXPECT_EQ(tight.err.find("too viscous"), std::string::npos) << tight.err;
  // Asked for less than round-off allows with cycles without a practical
  // bound, it cycled for ever; it was told to raise solver.max_cycles with
  // 10000.
  const Result below_round_off =
      map_run(dir, 33, "--set solver.tolerance=1e-300 --set solver.max_cycles=2000000000");
  expect_failed_run(dir, below_round_off, "stopped converging at a residual of ");
  EXPECT_TRUE(below_round_off.err.ends_with(
      ", the round-off of its pressure (it fell by less than half in its last 10 cycles): "
      "solver.tolerance = 1e-300 is below what it can reach; raise solver.tolerance\n"))
      << below_round_off.err;
  // A tolerance the start meets and the steps cannot: with 1e-16 on 33^2 each
  // step spent all its attempts and halvings at round-off (29 steps in 300 s).
  const Result steps_below_round_off =
      map_run(dir, 33, "--set solver.tolerance=1e-16 --set solver.max_cycles=60");
  expect_failed_run(dir, steps_below_round_off, "the film pressure stopped converging at a ");
  EXPECT_TRUE(steps_below_round_off.err.ends_with(
      "solver.tolerance = 1e-16 is below what it can reach; raise solver.tolerance\n"))
      << steps_below_round_off.err;
  EXPECT_EQ(steps_below_round_off.err.find("time step 0 "), std::string::npos);
  // ... nor is a film given too few cycles to judge its fall (it was said to
  // be too viscous).
  const Result few = map_run(dir, 65, "--set case.M=20 --set case.L=20 --set solver.max_cycles=2");
  expect_failed_run(dir, few, "was still converging when solver.max_cycles = 2 ran out");
  // ... nor a film whose pressure is bounded: an isoviscous one (it was said
  // to be too viscous, "unless Delta0^2 > 0").
  const Result slow = map_run(dir, 33,
                              "--set body.elastic=false --set case.L=0 --set case.M=1e-2 --set "
                              "time.Delta0=10 --set time.T_end=0.5");
  expect_failed_run(dir, slow,
                    "in solver.max_cycles = 20 cycles, although an isoviscous film has "
                    "a bounded pressure at any start: the solver did not converge it");
  EXPECT_EQ(slow.err.find("too viscous"), std::string::npos) << slow.err;
  const Result ok = map_run(dir, 65, "--set case.M=20 --set case.L=20 --set time.T_end=0.05");
  ASSERT_EQ(ok.exit_code, 0) << ok.err;
  EXPECT_NEAR(results_of(dir).at("initial_force").get<double>(), 0.13, 0.01);
}

TEST(CaseMap, ProbeWavinessDeeperThanTheGapIsBadInput) {
  TempDir dir;
  const Result r = map_run(dir, 33, "--set surface.waviness_amplitude=100");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.err.rfind("ehlsim: error: surface.waviness_amplitude = 100: must be < ", 0), 0u)
      << r.err;
  EXPECT_NE(r.err.find("must be > 0 at every grid point) (--set)\n"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir / "run"));
  // Just below the largest amplitude the message allows, the input is taken.
  const std::string text = r.err.substr(r.err.find("must be < ") + 10);
  const double largest = std::stod(text);
  EXPECT_GT(largest, 1.0);  // at least Delta0: the cosine is at most 1
  const Result ok = map_run(
      dir, 33,
      "--set time.T_end=1e-3 --set surface.waviness_amplitude=" + std::to_string(0.999 * largest));
  EXPECT_NE(ok.exit_code, 2) << ok.err;
}

TEST(CaseMap, ProbeLargeMNeedsMorePoints) {
  // M = 10000 on 65^2 used to keep h_min < 0 in 61 rows.
  TempDir dir;
  const Result r = map_run(dir, 65, "--set case.M=10000");
  expect_failed_run(dir, r, "negative film h_min = -");
  EXPECT_NE(r.err.find("use more points (grid.points = 65)\n"), std::string::npos) << r.err;
}

TEST(CaseMap, ProbeTimeStepsTooLongForTheContact) {
  // time.dT = 1.5 to 3 on 33^2 used to end with exit 0 after 2 to 4 steps
  // (at 3 with a rebound faster than the ball arrived): the dry contact,
  // 3.2181 long, needs 4 steps at least.
  TempDir dir;
  expect_refused_at_once(
      "--set grid.points=33 --set time.dT=3 --out " + quote((dir / "run").string()),
      "time.dT = 3: must be <= 0.8045: the dry contact at time.V0 = 1 lasts "
      "3.218, and a run needs at least 4 steps in it (--set)");
  EXPECT_FALSE(fs::exists(dir / "run"));
  // At 4 steps per contact M = 1000's film goes negative: the step shares the blame.
  const Result coarse = map_run(dir, 33, "--set time.dT=0.8 --set case.M=1000");
  expect_failed_run(dir, coarse, "negative film h_min = -");
  EXPECT_NE(coarse.err.find("use more points (grid.points = 33), or a shorter time step (time.dT "
                            "= 0.8, the mesh 0.09375)\n"),
            std::string::npos)
      << coarse.err;
}

TEST(CaseMap, ProbeRoelandsWithAHugeZEnds) {
  // The examples/roelands-dh.toml with z = 1e6 (now bad input beside
  // the file's case.L) never ended: every step unconverged, nothing capped
  // the run.  Its lubricant without the file:
  TempDir dir;
  const std::string roelands_dh =
      "--set lubricant.viscosity=roelands --set lubricant.density=dowson-higginson "
      "--set lubricant.eta0=0.04 --set lubricant.ph_star=1e9";
  // It ends at the start ("did not converge") or, with the coarse levels'
  // logarithmic mean that solver.coarse_face_mean = "auto" gives its L, a few
  // steps later ("no attempt converged").
  expect_failed_run(dir, map_run(dir, 65, roelands_dh + " --set lubricant.z=1e6"), "converge");
}

/// Exit 0, lift-off, every step converged; the run's results.
nlohmann::json expect_lift_off_with_every_step_converged(const TempDir& dir, const Result& r) {
  EXPECT_EQ(r.exit_code, 0) << r.err;
  if (r.exit_code != 0) return nlohmann::json::object();
  const nlohmann::json res = results_of(dir);
  EXPECT_EQ(res.at("outcome"), "lift_off");
  EXPECT_EQ(res.at("unconverged_steps"), 0);
  return res;
}

TEST(CaseMap, PaperCaseLiftsOffWithEveryStepConverged) {
  TempDir dir;
  const nlohmann::json res = expect_lift_off_with_every_step_converged(dir, map_run(dir, 65, ""));
  ASSERT_FALSE(res.empty());
  const double V = res.at("rebound_speed").get<double>();
  EXPECT_GT(V, 0.5);  // some loss in the film ...
  EXPECT_LT(V, 1.0);  // ... and no gain
  const nlohmann::json run = nlohmann::json::parse(read_file(dir / "run" / "run.json"));
  EXPECT_LT(2 * res.at("steps").get<int>(), run.at("parameters").at("time").at("max_steps"));
}

TEST(CaseMap, RigidViscousBallComesToRest) {
  // No elastic energy to give back: the squeeze film stops the ball.
  TempDir dir;
  const Result r = ehlsim(
      "impact --set grid.points=65 --set case.M=1 --set case.L=0 "
      "--set body.elastic=false --out " +
      quote((dir / "run").string()));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("at rest in the film at T = "), std::string::npos) << r.out;
  const nlohmann::json res = results_of(dir);
  EXPECT_EQ(res.at("outcome"), "at_rest");
  EXPECT_FALSE(res.at("lifted_off").get<bool>());
  EXPECT_TRUE(res.at("rebound_speed").is_null());
  EXPECT_LE(res.at("final_energy").get<double>(), 1e-4);
  EXPECT_GT(res.at("impulse").get<double>(), 0.95);  // the momentum V0 taken out, not more
  EXPECT_LT(res.at("impulse").get<double>(), 1.01);
}

TEST(CaseMap, ARigidBallNeverRebounds) {
  // No elastic energy: M = 20, L = 0 "lifted off" at 0.37 V0 on 33^2 with
  // exit 0 (a halved step overshot); M = 10 comes to rest.
  TempDir dir;
  const std::string rigid = "--set body.elastic=false --set case.L=0 ";
  expect_failed_run(dir, map_run(dir, 33, rigid + "--set case.M=20"),
                    "the rigid ball moves away from the flat (dDelta/dT = ");
  const Result rest = map_run(dir, 33, rigid + "--set case.M=10");
  ASSERT_EQ(rest.exit_code, 0) << rest.err;
  EXPECT_EQ(results_of(dir).at("outcome"), "at_rest");
  // M = 100 closes in further than 33^2 resolves; a Roelands law with z = 0
  // is no piezoviscous film (it was told to use a smaller L).
  TempDir other;
  const Result closer = map_run(other, 33,
                                "--set body.elastic=false --set case.M=100 --set "
                                "lubricant.viscosity=roelands --set lubricant.ph_star=1e9 --set "
                                "lubricant.eta0=0.04 --set lubricant.z=0");
  expect_failed_run(other, closer, "a rigid ball's film thins without bound as it closes in");
  EXPECT_EQ(closer.err.find("piezoviscous"), std::string::npos) << closer.err;
}

TEST(CaseMap, ARigidBallInAPiezoviscousFilmKeepsNoStepAboveTheTolerance) {
  // Closing in on a rigid flat through a Barus film, the pressure grows
  // without bound (p_center 0.11, 0.22, 0.36 at T = 0.47, 0.56, 0.59 on
  // 129^2).  Steps no attempt converged were kept within 100 times the
  // tolerance: 19 of 43 to T = 1 on 129^2, exit 0, p_max between 0.1 and
  // 0.38.  Now the run ends there, at the same Delta on 65^2 and 129^2.
  TempDir dir;
  const Result r = map_run(dir, 65,
                           "--set case.M=37.77 --set case.L=11 --set time.Delta0=0.631 "
                           "--set time.V0=0.481 --set body.elastic=false");
  expect_failed_run(dir, r, "time step 13 (T = 0.60938): no attempt converged (residual ");
  EXPECT_NE(r.err.find("; Delta = 0.3444, dDelta/dT = -0.45"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("a rigid ball in a piezoviscous film"), std::string::npos) << r.err;
}

TEST(CaseMap, StartingFurtherAwayResolvesTheViscousStart) {
  // The hint of ProbeSmallMOnA33Grid: the same case from Delta0 = 2 lifts off.
  TempDir dir;
  const Result r = map_run(dir, 65, "--set case.M=1 --set time.Delta0=2");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(results_of(dir).at("outcome"), "lift_off");
}

TEST(CaseMap, AStartThatStoresMoreThanTheImpactEnergyWarnsAndKeepsItsEnergyBound) {
  // V0 = Delta0 = 1e-3: the film at T = 0 holds 20 times the impact energy in
  // the solids, and the rebound took it back (3.6 V0) with no word before.
  // The energy bound still holds: V <= sqrt(1 + stored share) V0.
  TempDir dir;
  const Result r = ehlsim(
      "impact --set grid.points=65 --set time.V0=1e-3 --set time.Delta0=1e-3 "
      "--out " +
      quote((dir / "run").string()));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("ehlsim: warning: the film at T = 0 stores "), std::string::npos) << r.err;
  const nlohmann::json res = results_of(dir);
  ASSERT_EQ(res.at("warnings").size(), 1u);
  const double V0 = 1e-3;
  const double share = res.at("initial_elastic_energy").get<double>() / (0.5 * V0 * V0);
  EXPECT_GT(share, kStartEnergyWarning);
  const double V = res.at("rebound_speed").get<double>();
  EXPECT_GT(V, V0);                                  // the stored energy came back ...
  EXPECT_LT(V, std::sqrt(1.0 + share) * V0 * 1.02);  // ... and no more (2 %: the grid)
  // The paper's start stores 1 % at most: no such warning (PaperCase... and
  // DomainEdges check the warnings of M = 100 and M = 1000).
  EXPECT_TRUE(start_note(0.01 * 0.5, ImpactConfig{}).empty());
}

TEST(CaseMap, ASlowBallsSqueezeFilmIsNotTakenForADivergedOne) {
  // V0 = 1e-6 from Delta0 = 0.01: the squeeze film spreads its force wider
  // than a Hertz contact, 6.4 times the dry force of the run's energy at the
  // first step, and the bound of 4 dry forces ended the run as "diverged".
  // The bound is now the most force the energy can hold on the domain.
  TempDir dir;
  const Result r = map_run(dir, 33, "--set time.V0=1e-6 --set time.Delta0=0.01 --set time.T_end=1");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(results_of(dir).at("outcome"), "t_end");
}

// ---------------------------------------------------------------------------
// The domain's edges
// ---------------------------------------------------------------------------

TEST(EdgeBand, CoversATenthOfTheSideOnEveryGridAndTheQuadrantCountsForTheDomain) {
  // A uniform pressure: the band within a tenth of the side from the four
  // edges is 1 - 0.8^2 = 0.36 of the square, up to the half meshes at the
  // boundary (0.347 on 33^2, 0.358 on 257^2); the mirrored quadrant of a grid
  // gives its full grid's sum.
  for (const int n : {33, 65, 129, 257}) {
    const Grid2D full(n, 1.5);
    const Grid2D quadrant = full.quadrant();
    const double h = full.h();
    const double band_area = edge_band_sum(full, Field(full, 1.0)) * h * h;
    EXPECT_NEAR(band_area / 9.0, 0.36, 0.5 / (n - 1)) << n;
    EXPECT_NEAR(edge_band_sum(quadrant, Field(quadrant, 1.0)) * h * h, band_area, 1e-12) << n;
  }
  // A pressure at the centre has nothing in the band, one at an edge all of it.
  const Grid2D grid(65, 1.5);
  Field centre(grid, 0.0), edge(grid, 0.0);
  centre(32, 32) = edge(3, 40) = 1.0;
  EXPECT_EQ(edge_band_sum(grid, centre), 0.0);
  EXPECT_EQ(edge_band_sum(grid, edge), 1.0);
  EXPECT_THROW((void)edge_band_sum(grid.quadrant(), Field(grid.quadrant(), 1.0), {.x_max = false}),
               std::invalid_argument);
}

TEST(DomainEdges, ARunWhoseSqueezeFilmReachesTheEdgesSaysSoAndItsResultMoves) {
  // On the paper's domain the squeeze film of the approach reaches the edges:
  // at M = 10 the edge band takes 3 % of the ball's momentum, and on the
  // domain doubled at the same mesh the ball rebounds 0.19 V0 slower
  // (docs/validation.md, "The size of the domain").  At M = 1000 the band
  // takes 0.03 % and the rebound hardly moves.
  TempDir dir;
  const std::string doubled = " --set grid.points=129 --set grid.half_width=3 ";
  const auto rebound_on = [&](const std::string& options) {
    const Result r = ehlsim("impact --quiet" + options + " --out " + quote((dir / "run").string()));
    EXPECT_EQ(r.exit_code, 0) << r.err;
    return results_of(dir).at("rebound_speed").get<double>();
  };
  const Result viscous =
      ehlsim("impact --set grid.points=65 --set case.M=10 --out " + quote((dir / "run").string()));
  ASSERT_EQ(viscous.exit_code, 0) << viscous.err;
  EXPECT_NE(viscous.err.find("ehlsim: warning: the film within a tenth of the side from the "
                             "domain's edges took "),
            std::string::npos)
      << viscous.err;
  EXPECT_NE(viscous.err.find("widen it at the same mesh (grid.half_width = 3 with grid.points = "
                             "129 doubles it) and compare\n"),
            std::string::npos)
      << viscous.err;
  const nlohmann::json viscous_results = results_of(dir);
  EXPECT_GT(viscous_results.at("edge_impulse").get<double>(), kEdgeImpulseWarning);
  ASSERT_EQ(viscous_results.at("warnings").size(), 1u);
  const double viscous_rebound = viscous_results.at("rebound_speed").get<double>();
  EXPECT_LT(rebound_on(doubled + "--set case.M=10"), viscous_rebound - 0.1);

  const Result stiff = ehlsim("impact --set grid.points=65 --set case.M=1000 --out " +
                              quote((dir / "run").string()));
  ASSERT_EQ(stiff.exit_code, 0) << stiff.err;
  EXPECT_EQ(stiff.err.find("warning"), std::string::npos) << stiff.err;
  EXPECT_TRUE(results_of(dir).at("warnings").empty());
  EXPECT_LT(results_of(dir).at("edge_impulse").get<double>(), 0.1 * kEdgeImpulseWarning);
  const double stiff_rebound = results_of(dir).at("rebound_speed").get<double>();
  EXPECT_NEAR(rebound_on(doubled + "--set case.M=1000"), stiff_rebound, 0.005);
  // --quiet prints no warning; run.json still carries it.
  const Result quiet = map_run(dir, 65, "--set case.M=10");
  EXPECT_EQ(quiet.err, "");
  EXPECT_EQ(results_of(dir).at("warnings").size(), 1u);
}

/// The shortest interval of the default case on `points`^2 with `options`,
/// as a fraction of its time step, after checking that it lifts off with
/// every step converged (-1 if not).
double shortest_interval_of_converged_run(int points, const std::string& options) {
  TempDir dir;
  const nlohmann::json res =
      expect_lift_off_with_every_step_converged(dir, map_run(dir, points, options));
  if (res.empty()) return -1.0;
  const double dT = 3.0 / (points - 1);
  // convergence.csv: step,T,dt,attempt,damping,cycle,residual
  std::istringstream csv(read_file(dir / "run" / "convergence.csv"));
  std::string line;
  std::getline(csv, line);
  double shortest = dT;
  while (std::getline(csv, line)) {
    const std::size_t first = line.find(','), second = line.find(',', first + 1);
    shortest = std::min(shortest, std::stod(line.substr(second + 1)));
  }
  return shortest / dT;
}

TEST(HalvedSteps, AQuarterThatWouldEndTheRunIsHalvedFurther) {
  // M = 100, L = 40 on 129^2: the step to T = 3.914 (the pocket's collapse)
  // converged in none of its quarters (residual 1.8e-3, beyond the 100 times
  // solver.tolerance a run keeps) and ended the run with exit 1.  Its
  // quarters are now halved further (down to dT / 32 at most), and every
  // step converges.  With the coarse levels' mean the step was found with:
  // with the logarithmic one that "auto" gives at L >= 20 quarters suffice.
  const double shortest =
      shortest_interval_of_converged_run(129, "--set case.L=40 --set solver.coarse_face_mean=same");
  EXPECT_LT(shortest, 0.25 * (1.0 - 1e-9));
  EXPECT_GE(shortest, 1.0 / 32.0 * (1.0 - 1e-9));
}

TEST(HalvedSteps, AQuarterAboveTheToleranceIsHalvedOnceMore) {
  // M = 100, L = 20 on 257^2 kept the step to T = 4.1016 (the pocket's
  // collapse) at 5.1e-5, five times solver.tolerance, when halving stopped at
  // quarters (unconverged_steps 1); with eighths every step converges.  (The
  // coarse levels' mean of then: see AQuarterThatWouldEndTheRunIsHalvedFurther.)
  EXPECT_NEAR(
      shortest_interval_of_converged_run(257, "--set case.L=20 --set solver.coarse_face_mean=same"),
      1.0 / 8.0, 1e-9);
}

TEST(HalvedSteps, TheImpulseIsTheMomentumTheBallGainedWhenAWholeIntervalIsKept) {
  // With one cycle per attempt most steps fail and are halved; where the
  // halves end further above the tolerance, the whole interval's iterate is
  // kept (ImpactProblem.cpp, keep_whole_interval).  The halves' impulse was
  // then counted as well as the whole's: 0.263 too much in run.json here
  // (and 6.3e-4 for L = 20 on 1025^2).  The ball's momentum balance is
  // exact in the scheme (Newmark's velocity and the impulse add the same
  // trapezoidal forces): impulse = V0 + rebound speed to rounding.
  // (To T = 4.1: its last step, at T = 4.22, kept a pressure that vanished
  // unconverged, which is no lift-off; the ball speed of timeseries.csv has
  // 10 digits.)
  TempDir dir;
  const Result r = map_run(dir, 33, "--set solver.max_cycles=1 --set time.T_end=4.1");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json res = results_of(dir);
  EXPECT_EQ(res.at("outcome"), "t_end");
  EXPECT_GT(res.at("unconverged_steps").get<int>(), 0);  // the kept whole intervals among them
  const std::string csv = read_file(dir / "run" / "timeseries.csv");
  const std::string last = csv.substr(csv.rfind('\n', csv.size() - 2) + 1);
  const double speed = std::stod(last.substr(last.find(',', last.find(',') + 1) + 1));
  EXPECT_GT(speed, 0.9);  // moving away
  EXPECT_NEAR(res.at("impulse").get<double>(), 1.0 + speed, 1e-9);
}

TEST(HalvedSteps, APressureThatVanishedUnconvergedIsNoLiftOff) {
  // The same run to lift-off kept, at T = 4.22, a pressure that vanished in
  // a step no attempt converged (the force 0.029 the step before), and took
  // it for a lift-off with exit 0.
  TempDir dir;
  expect_failed_run(dir, map_run(dir, 33, "--set solver.max_cycles=1"),
                    "the pressure vanished in a step that no attempt converged (residual ");
}

TEST(CaseMap, TheStepCapEndsARunUntilLiftOff) {
  TempDir dir;
  const Result capped = map_run(dir, 33, "--set time.max_steps=5");
  expect_failed_run(dir, capped, "no lift-off after 5 steps (time.max_steps");
  // The paper's case keeps its squeeze film off the edges: no word of the domain.
  EXPECT_EQ(capped.err.find("domain"), std::string::npos) << capped.err;
  // An isoviscous M = 1 pushes a tenth of its momentum through the edge band
  // in its first ten steps (12.5 % on 65^2 to lift-off, docs/validation.md):
  // its failure says that the domain decides it.
  const Result viscous = map_run(dir, 33, "--set case.M=1 --set case.L=0 --set time.max_steps=10");
  expect_failed_run(dir, viscous, "no lift-off after 10 steps (time.max_steps");
  EXPECT_NE(viscous.err.find("; by then the film within a tenth of the side from the domain's "
                             "edges took "),
            std::string::npos)
      << viscous.err;
  EXPECT_NE(viscous.err.find("(grid.half_width = 3 with grid.points = 65 doubles it)"),
            std::string::npos)
      << viscous.err;
  // A run to a given time is not capped.
  const Result r = map_run(dir, 33, "--set time.max_steps=1 --set time.T_end=0.5");
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(results_of(dir).at("outcome"), "t_end");
}

// ---------------------------------------------------------------------------
// Runaway inputs (issue 10): a start far away or slow
// ---------------------------------------------------------------------------

TEST(RunawayInputs, AStartTooSlowOrTooFarIsRefusedBeforeAnyWork) {
  // Both grew the dry-Hertz table at 400 MB/s before.
  expect_refused_at_once("--set time.V0=1e-9",
                         "time.V0 = 1e-09: must be in [1e-06, 1e+06] (--set)");
  // The message says what would fit, and names the key the user gave that
  // changes it: it blamed time.dT where no allowed dT would do, and the
  // default time.V0 = 1 for a start far away.
  const auto too_many = [](const std::string& key_value, const std::string& start,
                           const std::string& steps, const std::string& fixes) {
    return key_value + ": a run until lift-off from " + start + " may need " + steps +
           " time steps (the default time.max_steps, 4 (Delta0 / V0 + 3.2181 V0^-0.2) / dT); at "
           "most 10000000 are allowed: set " +
           fixes + ", or time.T_end or time.max_steps (--set)";
  };
  expect_refused_at_once(
      "--set time.V0=1e-6",
      too_many("time.V0 = 1e-06",
               "time.Delta0 = 1 at time.V0 = 1e-06 with time steps of dT = 0.01172", "3.41e+08",
               "a time.dT of 0.401 or more, or a time.Delta0 of 0.0292 or less"));
  expect_refused_at_once(
      "--set time.Delta0=1e6",
      too_many("time.Delta0 = 1000000",
               "time.Delta0 = 1e+06 at time.V0 = 1 with time steps of dT = 0.01172", "3.41e+08",
               "a time.dT of 0.401 or more, or a time.Delta0 of 29200 or less"));
  expect_refused_at_once("--set time.T_end=1e9",
                         "time.T_end = 1000000000: needs 8.53e+10 time steps of time.dT = "
                         "0.01172; at most 10000000 are allowed (--set)");
  expect_refused_at_once(
      "--set time.dT=1e-6",
      too_many("time.dT = 1e-06", "time.Delta0 = 1 at time.V0 = 1 with time steps of dT = 1e-06",
               "1.69e+07", "a time.dT of 1.69e-06 or more"));
  expect_refused_at_once("--set time.dT=0.7 --set time.Delta0=1e8",
                         too_many("time.Delta0 = 100000000",
                                  "time.Delta0 = 1e+08 at time.V0 = 1 with time steps of dT = 0.7",
                                  "5.71e+08", "a time.Delta0 of 1.74e+06 or less"));
  expect_refused_at_once(
      "--set body.elastic=false --set grid.half_width=1e-8",
      too_many("grid.half_width = 1e-08",
               "time.Delta0 = 1 at time.V0 = 1 with time steps of dT = 7.813e-11", "2.16e+11",
               "a time.dT of 1.69e-06 or more"));
  expect_refused_at_once(
      "--set time.dT=1e-6 --set time.Delta0=1e9",
      too_many("time.Delta0 = 1000000000",
               "time.Delta0 = 1e+09 at time.V0 = 1 with time steps of dT = 1e-06", "4e+15",
               "a time.Delta0 of 2e+06 or less with a time.dT of 0.804"));
  // A closer start the grid would not resolve, or a waviness would cut, is
  // not offered; the key named is one the user gave (it was time.Delta0 = 1,
  // the default).
  expect_refused_at_once(
      "--set time.V0=1e-6 --set time.Delta0=1e4 --set grid.half_width=1000 --set grid.points=17 "
      "--set time.dT=1e-3",
      "time.Delta0 = 10000: a run until lift-off from time.Delta0 = 10000 at time.V0 = 1e-06 with "
      "time steps of dT = 0.001 may need 4e+13 time steps (the default time.max_steps, 4 (Delta0 / "
      "V0 + 3.2181 V0^-0.2) / dT); at most 10000000 are allowed: set time.T_end or time.max_steps "
      "(--set)");
  expect_refused_at_once(
      "--set time.V0=0.00779 --set time.Delta0=7.24e+06 --set time.dT=0.00437 --set "
      "grid.half_width=799 --set grid.points=17",
      too_many("time.Delta0 = 7240000",
               "time.Delta0 = 7.24e+06 at time.V0 = 0.00779 with time steps of dT = 0.00437",
               "8.51e+11", "a time.Delta0 of 41200 or less with a time.dT of 2.12"));
  expect_refused_at_once(
      "--set body.elastic=false --set grid.half_width=1.2e-5 --set grid.points=17",
      too_many("grid.half_width = 1.2e-05",
               "time.Delta0 = 1 at time.V0 = 1 with time steps of dT = 1.5e-06", "1.12e+07",
               "a time.dT of 1.69e-06 or more, or a time.Delta0 of 0.531 or less"));
  expect_refused_at_once("--set time.dT=1e-8 --set time.T_end=1",
                         "time.dT = 1e-08: needs 1e+08 time steps to time.T_end = 1; at most "
                         "10000000 are allowed: use a longer time.dT or an earlier time.T_end "
                         "(--set)");
  // One so short that the 1/dT terms overflow: "the multigrid iteration
  // diverged" at step 1 (exit 1), as if the solver had failed.
  for (const char* dT : {"1e-308", "1e-320", "1e-13"})
    expect_refused_at_once(std::string("--set time.dT=") + dT + " --set time.max_steps=3",
                           std::string("time.dT = ") + dT + ": must be >= 1e-12 (--set)");
  expect_refused_at_once(
      "--set body.elastic=false --set time.Delta0=1e-26 --set grid.half_width=1e-12 --set "
      "time.T_end=1e-12",
      "grid.half_width = 1e-12: gives a mesh, and so a default time.dT, of 7.812e-15; it must be "
      ">= 1e-12: set time.dT or use a coarser mesh (--set)");
}

TEST(RunawayInputs, ASlowStartToAGivenTimeRunsWithABoundedDryReference) {
  // The spike analysis needs the dry contact radius of this start: its
  // trajectory must not tabulate the 1e6 time units of flight before contact
  // (the slowest start time.V0 allows; 1e-9 before it had a range).
  TempDir dir;
  const auto start = std::chrono::steady_clock::now();
  const Result r = ehlsim(
      "impact --quiet --set grid.points=17 --set solver.coarsest_points=9 --set time.V0=1e-6 "
      "--set time.T_end=0.5 --out " +
      quote((dir / "run").string()));
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_LT(seconds, 30.0);
  rusage usage{};
  ASSERT_EQ(getrusage(RUSAGE_CHILDREN, &usage), 0);
  constexpr long kMostKilobytes = 500 * 1024;  // the largest child of this test program
  EXPECT_LT(usage.ru_maxrss, kMostKilobytes);
  const nlohmann::json run = nlohmann::json::parse(read_file(dir / "run" / "run.json"));
  EXPECT_EQ(run.at("results").at("outcome"), "t_end");
}

}  // namespace
