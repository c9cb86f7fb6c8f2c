// The full impact solver (ImpactProblem) against the physics of model.md:
// analytic squeeze films of rigid bodies (isoviscous and Barus), the squeeze-film
// trajectory of a rigid ball, the multigrid convergence factors, the lubricated
// impact M = 100, L = 10 to lift-off, grid convergence, and FFT vs direct
// deformation inside the solver.
//
// Every run is small (at most 257^2, at most 64 steps on 257^2): the whole file
// takes ~85 s with one OpenMP thread (ctest sets OMP_NUM_THREADS=1).  Runs used by several tests
// are made once (function-local statics).  Key numbers are printed and stored
// with RecordProperty so that they can go into the docs.
#include <gtest/gtest.h>
#include <omp.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <exception>
#include <iomanip>
#include <iostream>
#include <limits>
#include <numbers>
#include <span>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "dynamics/DryHertz.hpp"
#include "grid/Grid.hpp"
#include "impact/AttemptPolicy.hpp"
#include "impact/ImpactConfig.hpp"
#include "impact/ImpactObserver.hpp"
#include "impact/ImpactProblem.hpp"
#include "impact/PressurePredictor.hpp"
#include "impact/Scaling.hpp"

using namespace ehlsim;

namespace {

constexpr double kPi = std::numbers::pi;
/// 3/(2 pi): dimensionless acceleration per unit force (model.md).
constexpr double kForceToAccel = 3.0 / (2.0 * kPi);

// ------------------------------------------------------------------ running

/// Everything a test wants to know about one run.
struct RunResult {
  ImpactConfig cfg;
  Grid2D grid;
  std::vector<StepRecord> records;
  RunSummary summary;
  double min_pressure = 0.0;  ///< minimum of the P field over every point and step
  int min_pressure_step = 0;
  Field last_P, last_H;  ///< fields of the last step
  /// Per step: radius of the pressure maximum along Y = 0, X >= 0 (the spike).
  std::vector<double> spike_radius;
  /// residuals[step][cycle]: from on_cycle (cycle 0 = before the first cycle).
  std::vector<std::vector<double>> residuals;
  double seconds = 0.0;
  std::string error;  ///< non-empty when run() threw
};

/// Records every step, the fields of the last one and the minimum pressure.
class Recorder final : public ImpactObserver {
 public:
  explicit Recorder(RunResult& out) : out_(out) {}
  void on_start(const Grid2D& grid) override { out_.grid = grid; }
  void on_step(const StepRecord& record, const Field& P, const Field& H, bool) override {
    out_.records.push_back(record);
    for (std::size_t k = 0; k < P.size(); ++k) {
      if (P[k] < out_.min_pressure) {
        out_.min_pressure = P[k];
        out_.min_pressure_step = record.step;
      }
    }
    out_.last_P = P;
    out_.last_H = H;
    const int n = P.n(), c = (n - 1) / 2;
    int i_max = c;
    for (int i = c; i < n; ++i)
      if (P(i, c) > P(i_max, c)) i_max = i;
    out_.spike_radius.push_back(out_.grid.x(i_max));
  }
  void on_cycle(const CycleRecord& c) override {
    if (static_cast<int>(out_.residuals.size()) <= c.step) out_.residuals.resize(c.step + 1);
    auto& r = out_.residuals[c.step];
    if (c.cycle == 0) r.clear();  // a retried step: keep the last attempt only
    if (static_cast<int>(r.size()) <= c.cycle) r.resize(c.cycle + 1);
    r[c.cycle] = c.residual;
  }
  void on_finish(const RunSummary& summary) override { out_.summary = summary; }

 private:
  RunResult& out_;
};

RunResult run_case(const ImpactConfig& cfg) {
  RunResult out;
  out.cfg = cfg;
  const auto start = std::chrono::steady_clock::now();
  try {
    ImpactProblem problem(cfg);
    Recorder recorder(out);
    out.summary = problem.run(recorder);
  } catch (const std::exception& e) {
    out.error = e.what();
  }
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::cout << "[run] n = " << cfg.grid_points << ", half_width = " << cfg.half_width
            << ", elastic = " << cfg.elastic << ", lambda_bar = " << cfg.lambda_bar
            << ", alpha_bar = " << cfg.alpha_bar << ", dT = " << cfg.dT << ": "
            << out.records.size() << " steps in " << std::fixed << std::setprecision(2)
            << out.seconds << " s" << std::defaultfloat << std::setprecision(6)
            << (out.error.empty() ? "" : "  ERROR: " + out.error) << "\n";
  return out;
}

/// A rigid (no deformation) squeeze film: lambda_bar, alpha_bar given directly.
/// The tolerance is tight because these tests measure discretization errors of
/// ~1e-3: the pressure-scaled residual hides smooth pressure errors (at the
/// default 1e-5 the central pressure is off by ~0.3%, the same size as the
/// discretization error being measured), so the algebraic error must be far below.
ImpactConfig rigid_config(double lambda_bar, double alpha_bar, int n, double half_width,
                          double T_end) {
  ImpactConfig cfg;
  cfg.lambda_bar = lambda_bar;
  cfg.alpha_bar = alpha_bar;
  cfg.elastic = false;
  cfg.grid_points = n;
  cfg.half_width = half_width;
  cfg.T_end = T_end;
  cfg.tolerance = 1e-10;
  cfg.max_cycles = 100;
  return cfg;
}

/// The paper's lubricated case (Barus, incompressible, elastic) with Moes M, L.
ImpactConfig moes_config(int n, double M = 100.0, double L = 10.0) {
  ImpactConfig cfg;
  cfg.M = M;
  cfg.L = L;
  cfg.lambda_bar = moes_lambda_bar(M);
  cfg.alpha_bar = moes_alpha_bar(M, L);
  cfg.grid_points = n;
  return cfg;
}

std::string str(double v, int precision = 6) {
  std::ostringstream s;
  s << std::setprecision(precision) << v;
  return s.str();
}

/// Prints and records one measured number.
void report(const std::string& key, double value, int precision = 6) {
  std::cout << "  " << key << " = " << str(value, precision) << "\n";
  ::testing::Test::RecordProperty(key, str(value, precision));
}

/// BDF2 derivative of Delta at the last record: the squeeze term the solver
/// actually used (the rigid gap is Delta + shape, so d(H)/dT = d(Delta)/dT).
double bdf2_last(const std::vector<StepRecord>& r, double dT) {
  const std::size_t n = r.size();
  return (1.5 * r[n - 1].Delta - 2.0 * r[n - 2].Delta + 0.5 * r[n - 3].Delta) / dT;
}

/// Isoviscous pressure of a rigid squeeze film on a disc of radius R with P = 0
/// on its rim (R = inf: unbounded): P = lambda (-V)/4 (1/H^2 - 1/H_R^2).
double disc_pressure(double lambda, double V, double Delta, double r, double R) {
  const double H = Delta + 0.5 * r * r;
  if (r > R) return 0.0;
  const double HR = std::isinf(R) ? std::numeric_limits<double>::infinity() : Delta + 0.5 * R * R;
  return 0.25 * lambda * (-V) * (1.0 / (H * H) - 1.0 / (HR * HR));
}

/// Force of that disc pressure: Int 2 pi r P dr = (pi lambda (-V)/2) (R^2/2)^2 / (Delta H_R^2)
/// (-> pi lambda (-V) / (2 Delta) for R -> inf).
double disc_force(double lambda, double V, double Delta, double R) {
  const double a = 0.5 * R * R, HR = Delta + a;
  return 0.5 * kPi * lambda * (-V) * a * a / (Delta * HR * HR);
}

/// G_R with dG_R/dDelta = (R^2/2)^2 / (Delta H_R^2), the force factor of a disc
/// of radius R: the rigid ball on that disc obeys V + (3 lambda/4) G_R(Delta) = const.
double G_disc(double Delta, double R) {
  const double a = 0.5 * R * R;
  return std::log(Delta) - std::log(Delta + a) + a / (Delta + a);
}

/// Delta where V + (3 lambda / 4) G_R(Delta) = V1 + (3 lambda / 4) G_R(Delta1) gives V = 0
/// (bisection; G_R is increasing).
double disc_stop(double lambda, double Delta1, double V1, double R) {
  const double target = G_disc(Delta1, R) + V1 / (0.75 * lambda);  // G_R(stop)
  double lo = 1e-6, hi = Delta1;
  for (int k = 0; k < 200; ++k) {
    const double mid = 0.5 * (lo + hi);
    (G_disc(mid, R) < target ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

/// Statistics of the residual reduction per multigrid cycle, r_c / r_{c-1}.
struct FactorStats {
  int count = 0;
  double geometric_mean = std::nan("");
  double median = std::nan("");
  double p90 = std::nan("");
  double max = std::nan("");
};

/// Factors of the steps whose time lies in [T_lo, T_hi).  Residuals below
/// `floor` are round-off and not counted as the start of a ratio.
FactorStats reduction_factors(const RunResult& run, double T_lo, double T_hi,
                              double floor = 1e-13) {
  std::vector<double> f;
  for (std::size_t s = 1; s < run.residuals.size() && s <= run.records.size(); ++s) {
    const double T = run.records[s - 1].T;
    if (T < T_lo || T >= T_hi) continue;
    const auto& r = run.residuals[s];
    for (std::size_t c = 1; c < r.size(); ++c)
      if (r[c - 1] > floor && r[c] > 0.0) f.push_back(r[c] / r[c - 1]);
  }
  FactorStats st;
  st.count = static_cast<int>(f.size());
  if (f.empty()) return st;
  double log_sum = 0.0;
  for (double v : f) log_sum += std::log(v);
  std::sort(f.begin(), f.end());
  st.geometric_mean = std::exp(log_sum / static_cast<double>(f.size()));
  st.median = f[f.size() / 2];
  st.p90 = f[(f.size() * 9) / 10];
  st.max = f.back();
  return st;
}

void report_factors(const std::string& name, const FactorStats& s) {
  std::cout << "  " << name << ": " << s.count << " cycles, geometric mean "
            << str(s.geometric_mean, 3) << ", median " << str(s.median, 3) << ", 90th percentile "
            << str(s.p90, 3) << ", max " << str(s.max, 3) << "\n";
  ::testing::Test::RecordProperty(name + "_geometric_mean", str(s.geometric_mean, 3));
  ::testing::Test::RecordProperty(name + "_median", str(s.median, 3));
  ::testing::Test::RecordProperty(name + "_p90", str(s.p90, 3));
  ::testing::Test::RecordProperty(name + "_max", str(s.max, 3));
}

/// Second-order error of the discrete rigid squeeze-film pressure peak,
/// relative to the central pressure: ~kPeakErrorCoefficient h^2 / Delta
/// (measured on 129^2 and 257^2 of [-4, 4]^2, Delta = 0.21 - 0.25).
constexpr double kPeakErrorCoefficient = 0.3;

/// Observed order of convergence from three grids refined by 2.
double observed_order(double coarse, double medium, double fine) {
  return std::log2(std::abs(coarse - medium) / std::abs(medium - fine));
}

/// Reports the values of one quantity on three refinements and its observed
/// order, as "<prefix>_<name>_<label>" lines; returns the order.
double report_order(const std::string& prefix, const std::string& name,
                    const std::array<std::string, 3>& labels, const StepRecord& a,
                    const StepRecord& b, const StepRecord& d, double StepRecord::*field) {
  const double order = observed_order(a.*field, b.*field, d.*field);
  const StepRecord* records[] = {&a, &b, &d};
  for (int k = 0; k < 3; ++k) report(prefix + "_" + name + "_" + labels[k], records[k]->*field, 9);
  report(prefix + "_" + name + "_order", order, 3);
  return order;
}

// ------------------------------------------------------------- shared runs

/// Test 1 and 4a: rigid isoviscous squeeze film, lambda_bar = 0.5, on [-4, 4]^2
/// with 257^2 points (h = dT = 1/32), 30 steps to T = 0.9375 (Delta ~ 0.25).
const RunResult& rigid_isoviscous_run() {
  static const RunResult run = run_case(rigid_config(0.5, 0.0, 257, 4.0, 0.9375));
  return run;
}

/// Test 3: rigid isoviscous ball, lambda_bar = 1, on [-8, 8]^2 with 257^2 points
/// (h = dT = 1/16), to T = 4: the ball stops near Delta = exp(-4/3).
const RunResult& rigid_stop_run() {
  static const RunResult run = run_case(rigid_config(1.0, 0.0, 257, 8.0, 4.0));
  return run;
}

/// Tests 4b and 5: the lubricated impact M = 100, L = 10 on 129^2 with the
/// default solver settings, to lift-off (T_end = 6 only guards against a run
/// that never lifts off; the dry contact ends at 4.218).
const RunResult& lubricated_run() {
  static const RunResult run = [] {
    ImpactConfig cfg = moes_config(129);
    cfg.T_end = 6.0;
    return run_case(cfg);
  }();
  return run;
}

/// Test 6: M = 100, L = 10 to T = 0.75 on n^2 points with time step dT (0: h).
/// Converged far below the grid differences (~1e-5 in h_center): the default
/// tolerance leaves algebraic errors of ~2e-4 in h_center at T = 0.75 (129^2),
/// ten times the discretization error.
RunResult convergence_run(int n, double dT) {
  ImpactConfig cfg = moes_config(n);
  cfg.dT = dT;
  cfg.T_end = 0.75;
  cfg.tolerance = 1e-10;
  cfg.max_cycles = 60;
  return run_case(cfg);
}
/// The 129^2, dT = h run (also used for the multigrid factors of the approach).
const RunResult& convergence_run_129() {
  static const RunResult run = convergence_run(129, 0.0);
  return run;
}
struct ConvergenceRuns {
  RunResult n65, n129, n257;       // dT = h = 3/64, 3/128, 3/256
  RunResult n65_dT128, n65_dT256;  // 65^2 with dT = 3/128, 3/256
  RunResult n129_dT256;            // 129^2 with dT = 3/256
};
const ConvergenceRuns& convergence_runs() {
  static const ConvergenceRuns runs = [] {
    ConvergenceRuns r;
    r.n65 = convergence_run(65, 0.0);
    r.n129 = convergence_run_129();
    r.n257 = convergence_run(257, 0.0);
    r.n65_dT128 = convergence_run(65, 3.0 / 128.0);
    r.n65_dT256 = convergence_run(65, 3.0 / 256.0);
    r.n129_dT256 = convergence_run(129, 3.0 / 256.0);
    return r;
  }();
  return runs;
}

#define ASSERT_RAN(run)                                                \
  do {                                                                 \
    ASSERT_TRUE((run).error.empty()) << "run failed: " << (run).error; \
    ASSERT_GE((run).records.size(), 3u);                               \
  } while (0)

}  // namespace

// =================================================== 1. rigid squeeze film

// Rigid, isoviscous, incompressible: the Reynolds equation is linear with the
// uniform source dDelta/dT, and on an unbounded domain
//   P(r) = lambda (-dDelta/dT) / (4 H^2),   H = Delta + r^2/2   (model.md).
// On the square [-w, w]^2 with P = 0 on its edge, the maximum principle puts
// the exact pressure between the solutions on the inscribed disc (R = w) and
// the circumscribed disc (R = w sqrt 2), P_R = lambda (-V)/4 (1/H^2 - 1/H_R^2):
// that is the rigorous form of the domain-edge effect.  At the centre it is at
// most (Delta / H_w)^2 of the pressure (8.8e-4 here, w = 4, Delta = 0.245).
TEST(RigidSqueezeFilm, IsoviscousPressureMatchesTheAnalyticProfile) {
  const RunResult& run = rigid_isoviscous_run();
  ASSERT_RAN(run);
  const double lambda = run.cfg.lambda_bar, dT = run.grid.h();
  const StepRecord& last = run.records.back();
  const double Delta = last.Delta, V = last.dDelta_dT;
  const double D = bdf2_last(run.records, dT);  // the discrete squeeze rate
  const double P0 = disc_pressure(lambda, D, Delta, 0.0, INFINITY);
  const double R1 = run.cfg.half_width, R2 = std::sqrt(2.0) * R1;

  double err_bdf = 0.0, err_newmark = 0.0, below_inner = 0.0, above_outer = 0.0;
  const int n = run.grid.n, j = (n - 1) / 2;  // the row Y = 0
  for (int i = 0; i < n; ++i) {
    const double x = run.grid.x(i), p = run.last_P(i, j);
    err_bdf = std::max(err_bdf,
                       std::abs(p - disc_pressure(lambda, D, Delta, std::abs(x), INFINITY)) / P0);
    err_newmark = std::max(
        err_newmark, std::abs(p - disc_pressure(lambda, V, Delta, std::abs(x), INFINITY)) / P0);
    below_inner =
        std::max(below_inner, (disc_pressure(lambda, D, Delta, std::abs(x), R1) - p) / P0);
    above_outer =
        std::max(above_outer, (p - disc_pressure(lambda, D, Delta, std::abs(x), R2)) / P0);
  }
  const double edge = std::pow(Delta / (Delta + 0.5 * R1 * R1), 2);
  const double bdf_vs_newmark = std::abs(D - V) / std::abs(V);
  const double F = last.force;
  const double F_inner = disc_force(lambda, D, Delta, R1),
               F_outer = disc_force(lambda, D, Delta, R2);
  const double F_unbounded = 0.5 * kPi * lambda * (-D) / Delta;

  std::cout << "Rigid isoviscous squeeze film, lambda_bar = 0.5, 257^2 on [-4, 4]^2, T = " << last.T
            << "\n";
  report("rigid_Delta", Delta);
  report("rigid_dDelta_dT_newmark", V);
  report("rigid_dDelta_dT_bdf2", D);
  report("rigid_bdf2_vs_newmark_rel", bdf_vs_newmark, 3);
  report("rigid_P_center", run.last_P(j, j));
  report("rigid_P_center_analytic", P0);
  report("rigid_max_err_vs_analytic_bdf2_rel", err_bdf, 3);
  report("rigid_max_err_vs_analytic_newmark_rel", err_newmark, 3);
  report("rigid_edge_bound_rel", edge, 3);
  report("rigid_below_inner_disc_rel", below_inner, 3);
  report("rigid_above_outer_disc_rel", above_outer, 3);
  report("rigid_force", F);
  report("rigid_force_inner_disc", F_inner);
  report("rigid_force_outer_disc", F_outer);
  report("rigid_force_unbounded", F_unbounded);

  // The BDF2 derivative of Delta and the Newmark velocity are both O(dT^2)
  // approximations of dDelta/dT (dT^2 = 1e-3 here; measured 3.0e-4, and 1.3e-3
  // with dT = 1/16: the O(dT^2) ratio 4).
  EXPECT_LT(bdf_vs_newmark, 1e-3);
  // Discretization: the second-order error of the pressure peak (width
  // sqrt(2 Delta)), measured ~0.3 h^2 / Delta of P0: 1.0e-3 here (h = 1/32),
  // 5.6e-3 on 129^2 with h = 1/16 (the edge part removed, ratio 4.4: second
  // order).  The allowance is twice that estimate, 2.4e-3 here.
  const double kDiscretization = 2.0 * kPeakErrorCoefficient * dT * dT / Delta;
  EXPECT_LT(below_inner, kDiscretization) << "P below the inscribed-disc solution";
  EXPECT_LT(above_outer, kDiscretization) << "P above the circumscribed-disc solution";
  // Against the unbounded profile: discretization plus the edge effect.
  EXPECT_LT(err_bdf, kDiscretization + edge);
  // With the Newmark velocity instead of the BDF2 rate: plus their O(dT^2) difference.
  EXPECT_LT(err_newmark, kDiscretization + edge + bdf_vs_newmark);
  // Force: between the disc forces (rigorous), with the same relative
  // discretization allowance.  The unbounded formula is 5.4% higher (the
  // 1/r^4 tail beyond the domain carries that much of the load; the inscribed
  // disc misses 5.9%): the finite-domain force is the one to compare with.
  report("rigid_force_unbounded_excess_rel", F_unbounded / F - 1.0, 3);
  EXPECT_GT(F, F_inner * (1.0 - kDiscretization));
  EXPECT_LT(F, F_outer * (1.0 + kDiscretization));
}

// ======================================================== 2. rigid Barus

// With eta = exp(alpha P) the reduced pressure q = (1 - exp(-alpha P))/alpha
// obeys the isoviscous equation with the same source and boundary, so
// P = -(1/alpha) ln(1 - alpha P_iso) on any domain: the disc bounds carry over
// through this increasing map.  alpha_bar = 1, lambda_bar = 0.5 and T = 0.75
// keep alpha P_iso < 0.7 (measured below), away from the divergence at
// alpha P_iso = 1.
TEST(RigidSqueezeFilm, BarusPressureMatchesTheAnalyticProfile) {
  const RunResult run = run_case(rigid_config(0.5, 1.0, 129, 4.0, 0.75));
  ASSERT_RAN(run);
  const double lambda = run.cfg.lambda_bar, alpha = run.cfg.alpha_bar, dT = run.grid.h();
  const StepRecord& last = run.records.back();
  const double Delta = last.Delta;
  const double D = bdf2_last(run.records, dT);
  const auto barus = [alpha](double q) { return -std::log(1.0 - alpha * q) / alpha; };
  const double q0 = disc_pressure(lambda, D, Delta, 0.0, INFINITY);
  const double P0 = barus(q0);
  const double R1 = run.cfg.half_width, R2 = std::sqrt(2.0) * R1;

  double err = 0.0, below_inner = 0.0, above_outer = 0.0;
  const int n = run.grid.n, j = (n - 1) / 2;
  for (int i = 0; i < n; ++i) {
    const double r = std::abs(run.grid.x(i)), p = run.last_P(i, j);
    err = std::max(err, std::abs(p - barus(disc_pressure(lambda, D, Delta, r, INFINITY))) / P0);
    below_inner = std::max(below_inner, (barus(disc_pressure(lambda, D, Delta, r, R1)) - p) / P0);
    above_outer = std::max(above_outer, (p - barus(disc_pressure(lambda, D, Delta, r, R2))) / P0);
  }
  const double amplification = 1.0 / (1.0 - alpha * q0);  // dP/dP_iso at the centre
  const double edge = amplification * std::pow(Delta / (Delta + 0.5 * R1 * R1), 2);

  std::cout << "Rigid Barus squeeze film, lambda_bar = 0.5, alpha_bar = 1, 129^2 on [-4, 4]^2, T = "
            << last.T << "\n";
  report("barus_Delta", Delta);
  report("barus_alpha_P_iso_center", alpha * q0, 4);
  report("barus_P_center", run.last_P(j, j));
  report("barus_P_center_analytic", P0);
  report("barus_P_iso_center_analytic", q0);
  report("barus_max_err_rel", err, 3);
  report("barus_below_inner_disc_rel", below_inner, 3);
  report("barus_above_outer_disc_rel", above_outer, 3);

  ASSERT_LT(alpha * q0, 0.7) << "the case left the intended regime";
  // Second-order discretization on h = 1/16: ~0.3 h^2/Delta = 3.3e-3 of the
  // isoviscous pressure (test 1), amplified by dP/dP_iso = 1/(1 - alpha P_iso)
  // (2.7 at the centre here), so ~8.8e-3 (measured 7.9e-3 below the inner-disc
  // solution); the allowance is twice the estimate.
  const double discretization = 2.0 * amplification * kPeakErrorCoefficient * dT * dT / Delta;
  report("barus_discretization_allowance", discretization, 3);
  EXPECT_LT(below_inner, discretization);
  EXPECT_LT(above_outer, discretization);
  EXPECT_LT(err, discretization + edge);
  // The Barus pressure must exceed the isoviscous one for the same squeeze rate.
  EXPECT_GT(run.last_P(j, j), q0);
}

// ========================================= 3. rigid squeeze-film trajectory

// With the force pi lambda (-V) / (2 Delta) and d2Delta/dT2 = (3/(2 pi)) F,
// dV/dDelta = -(3 lambda/4)/Delta: V = -1 - (3 lambda/4) ln Delta and the ball
// stops at exp(-4/(3 lambda)) = 0.263597 for lambda = 1 (model.md).
//
// Domain edge.  On a disc of radius R the force factor 1/Delta becomes
// (R^2/2)^2/(Delta H_R^2) = dG_R/dDelta, so V + (3 lambda/4) G_R(Delta) is
// conserved and the stop moves down by ~4 (1 - Delta_s)/R^2 relatively
// (R = 4: 0.221, R = 8: 0.252, R = 16: 0.2606): the edge effect decays only
// like 1/R^2 because the early film (Delta ~ 1) is wide.  The square
// [-w, w]^2 lies between the discs R = w and R = w sqrt 2 (maximum principle:
// its force factor at each Delta lies between theirs), so its trajectory lies
// between theirs.  w = 8 brackets the stop in [0.2519, 0.2576], 2-4% below
// the unbounded value, at an affordable resolution (257^2, h = 1/16).
//
// Spatial error of the force at h = 1/16: ~0.3 h^2/Delta <~ 0.5% (test 1),
// i.e. ~0.6% on the stop (relative change of ln Delta_s); the time error
// (O(dT^2), dT times the rate 3 lambda/(4 Delta_s) = 0.18) is of the same
// order.  The allowances below are 1% on the stop and 1% of the travelled
// Delta V on the trajectory.
namespace {
constexpr double kTrajectoryAllowance = 0.01;
}

// One test with three parts (one run of ~20 s): (a) the trajectory after the
// first step, (b) the stop predicted from the state after the first step, (c)
// the stop from the true initial state Delta0 = 1, V0 = -1.
//
// (c) also needs the impulse of the first step right.  At T = 0 the rigid film
// already carries F(0) ~ pi lambda/2 (~1.5 here: the pressure of a rigid film
// is instantaneous), but the solver starts Newmark with A = 0
// (BallState{0, Delta0, -V0, 0}) and no pressure, so the first step misses
// (3/(2 pi)) F(0) dT/2 of momentum: an O(dT) error of V for the rest of the
// run (first-order time accuracy; see also GridConvergence).
TEST(RigidSqueezeFilm, BallFollowsTheSqueezeFilmLawAndStops) {
  const RunResult& run = rigid_stop_run();
  ASSERT_RAN(run);
  const double lambda = run.cfg.lambda_bar, dT = run.grid.h();
  const double R1 = run.cfg.half_width, R2 = std::sqrt(2.0) * R1;
  const StepRecord& first = run.records.front();
  const StepRecord& last = run.records.back();
  std::cout << "Rigid ball, lambda_bar = 1, 257^2 on [-8, 8]^2, dT = 1/16, to T = 4\n";
  {
    SCOPED_TRACE("(a) trajectory after the first step");
    // V^n - V^1 = (3 lambda / 4) (G(Delta^1) - G(Delta^n)), G between G_R1 and G_R2.
    double worst_margin = std::numeric_limits<double>::infinity(), max_dev_unbounded = 0.0;
    for (const StepRecord& r : run.records) {
      if (r.step < 2) continue;
      const double travelled = r.dDelta_dT - first.dDelta_dT;
      const double lo = 0.75 * lambda * (G_disc(first.Delta, R1) - G_disc(r.Delta, R1));
      const double hi = 0.75 * lambda * (G_disc(first.Delta, R2) - G_disc(r.Delta, R2));
      const double allowance = kTrajectoryAllowance * std::abs(hi);
      worst_margin = std::min(
          {worst_margin, (travelled - lo) / std::abs(hi), (hi - travelled) / std::abs(hi)});
      const double unbounded = 0.75 * lambda * std::log(first.Delta / r.Delta);
      max_dev_unbounded = std::max(max_dev_unbounded, std::abs(travelled - unbounded));
      EXPECT_GE(travelled, lo - allowance) << "step " << r.step << " T = " << r.T;
      EXPECT_LE(travelled, hi + allowance) << "step " << r.step << " T = " << r.T;
    }
    report("trajectory_step1_Delta", first.Delta);
    report("trajectory_step1_V", first.dDelta_dT);
    // Negative: outside the disc bracket by that fraction of the travelled Delta V.
    report("trajectory_worst_margin_in_disc_bracket_rel", worst_margin, 3);
    report("trajectory_max_dev_from_unbounded_law_after_step1", max_dev_unbounded, 3);
  }
  {
    SCOPED_TRACE("(b) stop predicted from the state after the first step");
    const double lo = disc_stop(lambda, first.Delta, first.dDelta_dT, R1);
    const double hi = disc_stop(lambda, first.Delta, first.dDelta_dT, R2);
    report("stop_T", last.T);
    report("stop_Delta", last.Delta);
    report("stop_V", last.dDelta_dT, 3);
    report("stop_band_from_step1_inner", lo);
    report("stop_band_from_step1_outer", hi);
    // V -> 0 exponentially, with rate 3 lambda/(4 Delta_s) ~ 3: V(4) ~ 1e-4 of V(0).
    EXPECT_LT(std::abs(last.dDelta_dT), 1e-3);
    EXPECT_LT(last.dDelta_dT, 0.0) << "a rigid squeeze film never rebounds";
    // The remaining travel |V| Delta_s / (3 lambda/4) is < 1e-3 of Delta_s.
    EXPECT_GE(last.Delta, lo * (1.0 - kTrajectoryAllowance));
    EXPECT_LE(last.Delta, hi * (1.0 + kTrajectoryAllowance));
  }
  {
    SCOPED_TRACE("(c) stop from the initial state Delta0 = 1, V0 = -1");
    const double lo = disc_stop(lambda, 1.0, -1.0, R1), hi = disc_stop(lambda, 1.0, -1.0, R2);
    const double unbounded = std::exp(-4.0 / (3.0 * lambda));
    // First-step impulse: Newmark gives V1 - V0 = (3/(2pi)) dT (F0 + F1)/2; the
    // film force at T = 0 is estimated by extrapolation, F0 ~ 2 F1 - F2 (O(dT^2)).
    const double F1 = run.records[0].force, F2 = run.records[1].force;
    const double F0 = 2.0 * F1 - F2;
    const double dV1 = first.dDelta_dT - (-1.0);
    const double dV1_expected = kForceToAccel * dT * 0.5 * (F0 + F1);
    report("stop_band_inner_disc", lo);
    report("stop_band_outer_disc", hi);
    report("stop_unbounded", unbounded);
    report("first_step_dV", dV1);
    report("first_step_dV_with_initial_force", dV1_expected);
    EXPECT_GE(last.Delta, lo * (1.0 - kTrajectoryAllowance))
        << "the ball went too far: the first step's momentum change is " << dV1
        << ", with the initial film force (~" << F0 << ") it would be " << dV1_expected;
    EXPECT_LE(last.Delta, hi * (1.0 + kTrajectoryAllowance));
    EXPECT_NEAR(dV1, dV1_expected, 0.05 * dV1_expected)
        << "the first step ignores the film force at T = 0 (Newmark started with A = 0)";
  }
}

// ========================================== 4. multigrid convergence factors

// The residual reduction per cycle, r_c / r_{c-1}, from on_cycle
// (pressure-scaled residual, default settings: V(3,2) cycles, coarsest grid
// 17^2, under-relaxation 0.4 Gauss-Seidel / 0.3 distributive).  The bounds are
// the measured values (solver of commit ecdf5d4) with a margin of ~1.4; the
// numbers are printed for the docs.
TEST(ImpactMultigrid, ReductionFactorRigid) {
  const RunResult& run = rigid_isoviscous_run();
  ASSERT_RAN(run);
  const FactorStats s = reduction_factors(run, 0.0, 1e9);
  std::cout << "Multigrid, rigid isoviscous, 257^2 (5 levels, 257 to 17), tolerance 1e-10\n";
  report_factors("mg_rigid", s);
  // Measured: geometric mean 0.29, 90th percentile 0.39, max 0.52 (a
  // textbook line-relaxation cycle on this Poisson-like problem reaches ~0.1;
  // the Gauss-Seidel under-relaxation 0.4 costs most of the difference).
  ASSERT_GT(s.count, 50);
  EXPECT_LT(s.geometric_mean, 0.4);
  EXPECT_LT(s.p90, 0.55);
  EXPECT_LT(s.max, 0.75);
}

// The residual measure hardly sees a smooth error of the pressure (its s_ij is
// the change that would remove a point's residual, docs/model.md section 8):
// with it alone, steps of the approach that pass the tolerance carry the
// error of the start.  The force criterion (solver.force_tolerance) cycles on
// until the force has settled: every step to T = 0.75 of the default settings
// then has the force of the run converged to 1e-10 (measured: within 1.2e-4,
// against 14 % with the measure alone).
TEST(ImpactConvergence, TheStoppingRuleBoundsTheForceErrorOfEveryStep) {
  const RunResult& converged = convergence_run_129();
  ASSERT_RAN(converged);
  ImpactConfig cfg = moes_config(129);
  cfg.T_end = 0.75;
  const auto largest_force_error = [&](const RunResult& run) {
    EXPECT_EQ(run.records.size(), converged.records.size());
    double largest = 0.0;
    for (std::size_t k = 0; k < std::min(run.records.size(), converged.records.size()); ++k) {
      const double exact = converged.records[k].force;
      largest = std::max(largest, std::abs(run.records[k].force - exact) / exact);
    }
    return largest;
  };
  const RunResult with_criterion = run_case(cfg);
  ASSERT_RAN(with_criterion);
  cfg.force_tolerance = 0.0;
  const RunResult measure_alone = run_case(cfg);
  ASSERT_RAN(measure_alone);
  const double error = largest_force_error(with_criterion);
  const double error_alone = largest_force_error(measure_alone);
  report("largest_relative_force_error_T_le_0.75", error);
  report("largest_relative_force_error_T_le_0.75_measure_alone", error_alone);
  EXPECT_LT(error, 1e-3);
  EXPECT_GT(error_alone, 1e-2);
}

// The approach's smooth error decayed at 0.6 per cycle with the Gauss-Seidel
// under-relaxation 0.4 at every point (0.16 without it): its first steps
// took twice the cycles.  The same force history either way, to the force
// criterion.
TEST(ImpactConvergence, FlowDominatedPointsWithoutUnderRelaxationHalveTheApproachsCycles) {
  ImpactConfig cfg = moes_config(65);
  cfg.T_end = 0.5;
  const RunResult plain = run_case(cfg);
  ASSERT_RAN(plain);
  cfg.relaxation.omega_flow_dominated = cfg.relaxation.omega_gauss_seidel;
  const RunResult relaxed = run_case(cfg);
  ASSERT_RAN(relaxed);
  const auto cycles = [](const RunResult& run) {
    int total = 0;
    for (const StepRecord& r : run.records) total += r.cycles;
    return total;
  };
  report("approach_cycles_65_omega_flow_dominated_1", cycles(plain));
  report("approach_cycles_65_omega_flow_dominated_0.4", cycles(relaxed));
  EXPECT_LT(cycles(plain), 0.7 * cycles(relaxed));
  ASSERT_EQ(plain.records.size(), relaxed.records.size());
  for (std::size_t k = 0; k < plain.records.size(); ++k)
    EXPECT_NEAR(plain.records[k].force, relaxed.records[k].force, 1e-3 * relaxed.records[k].force);
}

TEST(ImpactMultigrid, ReductionFactorLubricatedElastic) {
  const RunResult& run = lubricated_run();
  ASSERT_TRUE(run.error.empty()) << run.error;
  const FactorStats approach = reduction_factors(run, 0.0, 1.0);
  const FactorStats contact = reduction_factors(run, 1.0, 1e9);
  const FactorStats loading = reduction_factors(run, 1.0, 3.0);
  const FactorStats rebound = reduction_factors(run, 3.0, 1e9);
  std::cout << "Multigrid, M = 100, L = 10, 129^2, default settings\n";
  report_factors("mg_elastic_approach_T_lt_1", approach);
  report_factors("mg_elastic_contact_T_ge_1", contact);
  report_factors("mg_elastic_contact_1_to_3", loading);
  report_factors("mg_elastic_rebound_T_ge_3", rebound);
  // Measured (geometric means): approach 0.23, contact 0.20 (loading
  // 0.15, rebound 0.28).  In the rebound single cycles can raise the residual
  // (max ratio 4.5, at the step before lift-off), so only the means are bounded.
  ASSERT_GT(approach.count, 20);
  ASSERT_GT(contact.count, 200);
  EXPECT_LT(approach.geometric_mean, 0.35);
  EXPECT_LT(loading.geometric_mean, 0.25);
  EXPECT_LT(contact.geometric_mean, 0.3);
  EXPECT_LT(rebound.geometric_mean, 0.4);

  // With the default tolerance most approach steps stop after one or two
  // cycles; the asymptotic factor of the approach shows in the runs of the
  // grid-convergence test, converged to 1e-10 (T <= 0.75, film still thick).
  const FactorStats tight = reduction_factors(convergence_run_129(), 0.0, 1.0);
  report_factors("mg_elastic_approach_tol1e-10_129", tight);
  // Measured 0.43 (median 0.50): the thick film of the approach is the
  // rigid-like regime, where the Gauss-Seidel under-relaxation 0.4 limits the
  // smoothing (0.08 - 0.2 per cycle with 1.0 in a quick trial on 65^2).
  EXPECT_LT(tight.geometric_mean, 0.6);
}

// ============================================ 5. lubricated impact to lift-off

TEST(LubricatedImpact, M100L10ReachesLiftOffWithThePhysicsOfModelMd) {
  const RunResult& run = lubricated_run();
  ASSERT_TRUE(run.error.empty()) << run.error;
  const RunSummary& s = run.summary;
  std::cout << "Lubricated impact M = 100, L = 10, 129^2, default solver settings\n";
  report("lift_off_T", s.T_lift_off);
  report("rebound_speed", s.rebound_speed);
  report("max_force", s.max_force);
  report("T_max_force", s.T_max_force);
  report("min_h_center", s.min_h_center);
  report("T_min_h_center", s.T_min_h_center);
  report("impulse", s.impulse, 10);
  report("unconverged_steps", s.unconverged_steps);
  report("retried_steps", s.retried_steps);
  report("steps", s.steps);
  ASSERT_TRUE(s.lifted_off) << "no lift-off before T = " << s.T_final;
  std::cout << "  last steps (T, Delta, dDelta/dT, force, h_center, h_min, p_center, p_max, "
               "cycles, residual):\n";
  for (std::size_t k = run.records.size() >= 6 ? run.records.size() - 6 : 0; k < run.records.size();
       ++k) {
    const StepRecord& r = run.records[k];
    std::cout << "    " << r.T << "  " << r.Delta << "  " << r.dDelta_dT << "  " << r.force << "  "
              << r.h_center << "  " << r.h_min << "  " << r.p_center << "  " << r.p_max << "  "
              << r.cycles << "  " << r.residual << "\n";
  }

  // Squeeze film: the film carries load before dry contact (T = 1): already
  // at the first step, and more than 1% of the maximum force before T = 0.95.
  double force_before_contact = 0.0;
  for (const StepRecord& r : run.records) {
    if (r.T < 0.95) force_before_contact = std::max(force_before_contact, r.force);
    if (r.T < 1.0) {
      EXPECT_GT(r.force, 0.0) << "T = " << r.T;
    }
  }
  report("max_force_before_T_0.95", force_before_contact);
  EXPECT_GT(force_before_contact, 0.01 * s.max_force);

  // model.md expects lift-off later than the dry 4.218 (the paper: ~4.37 on
  // 1025^2).  ehlsim's converged solutions lift off at 4.16-4.20 on 65^2 to
  // 257^2 (LiftOffTimeConvergesUnderRefinement below; docs/validation.md):
  // the film force near the end is the Hertz force with the rim film h_min
  // ~ 0.16 as an offset, so the pressure vanishes when Delta ~ h_min, and the
  // entrapped pocket drains once it is a few mesh sizes wide.  Asserted here:
  // lift-off within the last 5 % of the dry contact or later.
  EXPECT_GT(s.T_lift_off, 4.2181 - 0.05 * 3.2181) << "lift-off far before the end of dry contact";

  // Viscous loss: 0 < rebound speed < 1 (the dry impact rebounds at 1).
  EXPECT_GT(s.rebound_speed, 0.0);
  EXPECT_LT(s.rebound_speed, 1.0);

  // Momentum: Newmark's velocity update is the trapezoidal rule of the
  // acceleration, so (3/(2pi)) Int F dT equals V_lift - (-1) to round-off
  // (~1e-15 per step): a consistency check of the bookkeeping.
  EXPECT_NEAR(s.impulse, s.rebound_speed + 1.0, 1e-10);
  // The same integral from the time series (trapezoidal rule, starting from
  // the film force at T = 0, which the time series has no row for).
  double trapezoid = 0.0, previous = s.initial_force, T_prev = 0.0;
  for (const StepRecord& r : run.records) {
    trapezoid += 0.5 * (previous + r.force) * (r.T - T_prev);
    previous = r.force;
    T_prev = r.T;
  }
  trapezoid *= kForceToAccel;
  EXPECT_NEAR(trapezoid, s.impulse, 1e-12);
  // Physically the impulse is below the dry 2 (rebound speed below 1).
  EXPECT_LT(s.impulse, 2.0);

  // Cavitation: P >= 0 at every point of every step (projection).
  EXPECT_GE(run.min_pressure, 0.0) << "at step " << run.min_pressure_step;
}

// Convergence of every step, to lift-off, including the spike phase and the
// collapse of the entrapped pocket (retries with more damping are allowed; a
// step kept above the tolerance is not a solution of the discrete equations).
TEST(LubricatedImpact, M100L10AllStepsAreConverged) {
  const RunResult& run = lubricated_run();
  ASSERT_TRUE(run.error.empty()) << run.error;
  report("unconverged_steps", run.summary.unconverged_steps);
  report("retried_steps", run.summary.retried_steps);
  EXPECT_EQ(run.summary.unconverged_steps, 0);
  for (const StepRecord& r : run.records)
    EXPECT_LT(r.residual, run.cfg.tolerance) << "step " << r.step << " T = " << r.T;
}

/// Time of the last step that still carries pressure (the pressure vanishes
/// between it and the lift-off step).
double last_pressurized_time(const RunResult& run) {
  double T = 0.0;
  for (const StepRecord& r : run.records)
    if (r.p_max > 0.0) T = r.T;
  return T;
}

// The moment the pressure vanishes is a property of the model, not of the
// grid: on 65^2 and 129^2 (dT = h) the last pressurized steps lie within one
// coarse time step of each other, and the lift-off steps too.
TEST(LubricatedImpact, LiftOffTimeConvergesUnderRefinement) {
  const RunResult& fine = lubricated_run();
  ASSERT_TRUE(fine.error.empty()) << fine.error;
  ImpactConfig cfg = moes_config(65);
  cfg.T_end = 6.0;
  const RunResult coarse = run_case(cfg);
  ASSERT_TRUE(coarse.error.empty()) << coarse.error;
  ASSERT_TRUE(coarse.summary.lifted_off && fine.summary.lifted_off);
  const double coarse_dT = Grid2D(65, cfg.half_width).h();
  report("T_last_pressure_65", last_pressurized_time(coarse));
  report("T_last_pressure_129", last_pressurized_time(fine));
  report("T_lift_off_65", coarse.summary.T_lift_off);
  report("T_lift_off_129", fine.summary.T_lift_off);
  EXPECT_NEAR(last_pressurized_time(coarse), last_pressurized_time(fine), coarse_dT);
  EXPECT_NEAR(coarse.summary.T_lift_off, fine.summary.T_lift_off, coarse_dT);
}

// Smoothness of the central pressure, central film and force histories.
// Measure: the second difference d2_n = x_{n+1} - 2 x_n + x_{n-1} relative to
// the range of x.  A history resolved in time, with features no faster than
// tau, has |d2| <~ (dT/tau)^2 range: with dT = 3/128 and tau >= 0.1, <= 0.055.
// A numerical oscillation gives |d2| ~ 4 x its amplitude with a sign change
// every step; so we also count sign changes among the |d2| > 1e-3 range (each
// inflection of a smooth history gives one; a zigzag gives one per step).
// The check stops at T = 4.0: later the dry contact radius shrinks by more than
// one mesh per step (dA/dT = -V/(2A), A(4.0) = 0.466, so |dA/dT| dT > h) and
// the inward-running spike cannot be resolved by any dT = h run.
TEST(LubricatedImpact, M100L10HistoriesAreSmooth) {
  const RunResult& run = lubricated_run();
  ASSERT_TRUE(run.error.empty()) << run.error;
  constexpr double kResolvedUntil = 4.0;
  struct History {
    const char* name;
    double StepRecord::*field;
  };
  for (const History h :
       {History{"p_center", &StepRecord::p_center}, History{"h_center", &StepRecord::h_center},
        History{"force", &StepRecord::force}}) {
    std::vector<double> x;
    for (const StepRecord& r : run.records)
      if (r.T <= kResolvedUntil + 1e-9) x.push_back(r.*(h.field));
    ASSERT_GT(x.size(), 10u);
    const double range =
        *std::max_element(x.begin(), x.end()) - *std::min_element(x.begin(), x.end());
    double max_d2 = 0.0;
    int sign_changes = 0;
    double last_significant = 0.0;
    for (std::size_t n = 1; n + 1 < x.size(); ++n) {
      const double d2 = x[n + 1] - 2.0 * x[n] + x[n - 1];
      max_d2 = std::max(max_d2, std::abs(d2) / range);
      if (std::abs(d2) > 1e-3 * range) {
        if (last_significant * d2 < 0.0) ++sign_changes;
        last_significant = d2;
      }
    }
    report(std::string("smooth_") + h.name + "_max_d2_over_range", max_d2, 3);
    report(std::string("smooth_") + h.name + "_sign_changes", sign_changes);
    EXPECT_LT(max_d2, 0.055) << h.name;
    EXPECT_LE(sign_changes, 4) << h.name;
  }
}

// The pressure spike of the rebound (model.md: it forms at the edge of the
// receding contact and travels inward, below the dry contact radius).
TEST(LubricatedImpact, M100L10SpikeTravelsInwardDuringRebound) {
  const RunResult& run = lubricated_run();
  ASSERT_TRUE(run.error.empty()) << run.error;
  const double dT = run.grid.h();
  const DryImpact dry = simulate_dry_hertz(1.0, 1.0, dT / 8.0, 6.0);
  const auto dry_radius = [&dry](double T) {
    for (std::size_t k = 0; k + 1 < dry.T.size(); ++k)
      if (dry.T[k] <= T && T <= dry.T[k + 1]) {
        const double w = (T - dry.T[k]) / (dry.T[k + 1] - dry.T[k]);
        return dry_contact_radius((1.0 - w) * dry.Delta[k] + w * dry.Delta[k + 1]);
      }
    return 0.0;
  };
  std::cout << "  T, spike radius (Y = 0, X >= 0), dry contact radius, p_max, p_center\n";
  for (std::size_t k = 0; k < run.records.size(); ++k) {
    const StepRecord& r = run.records[k];
    if (r.T < 3.4 || k % 2 != 0) continue;
    std::cout << "    " << r.T << "  " << run.spike_radius[k] << "  " << dry_radius(r.T) << "  "
              << r.p_max << "  " << r.p_center << "\n";
  }
  // The window: from T = 3.75 (dry contact radius 0.67) to T = 4.0 (0.47, the
  // end of the time-resolved rebound, see HistoriesAreSmooth).  On 129^2 the
  // spike shows on the axis from T ~ 3.6 - 3.7 (the paper: from 3.223 on
  // 1025^2; its width is a few meshes, so it needs the resolution to show early).
  double previous = std::numeric_limits<double>::infinity(), first = 0.0, last = 0.0;
  int in_window = 0;
  for (std::size_t k = 0; k < run.records.size(); ++k) {
    const StepRecord& r = run.records[k];
    if (r.T < 3.75 || r.T > 4.0 + 1e-9) continue;
    const double radius = run.spike_radius[k];
    if (in_window++ == 0) first = radius;
    last = radius;
    // A spike: off the centre, and higher than the central pressure by 10%.
    EXPECT_GT(radius, 0.0) << "T = " << r.T;
    EXPECT_GT(r.p_max, 1.1 * r.p_center) << "T = " << r.T;
    // Inside the dry contact radius of the same time.
    EXPECT_LT(radius, dry_radius(r.T)) << "T = " << r.T;
    // Inward: never outward from one step to the next (the position is
    // quantized by the mesh, h = 0.023, against ~0.02 of travel per step).
    EXPECT_LE(radius, previous) << "T = " << r.T;
    previous = radius;
  }
  report("spike_radius_T3.75", first);
  report("spike_radius_T4.0", last);
  ASSERT_GE(in_window, 10);
  EXPECT_LT(last, first - 0.1) << "the spike does not travel inward";
}

// ====================================================== 6. grid convergence

// h_center and the force at T = 0.75 (M = 100, L = 10, film already deformed:
// H(0) - Delta = 0.06).  BDF2 + Newmark + second-order differences: the
// observed order should be 2.  One test with three parts (the runs take ~45 s):
// (a) dT = h: 16, 32, 64 steps on 65^2, 129^2, 257^2, as the solver is used;
// (b) space alone: the same dT = 3/256 on the three grids (the time error is
//     then the same on all of them and drops out of the differences);
// (c) time alone: 65^2 with dT = 3/64, 3/128, 3/256.
TEST(ImpactGridConvergence, SecondOrderInSpaceAndTime) {
  const ConvergenceRuns& c = convergence_runs();
  for (const RunResult* r : {&c.n65, &c.n129, &c.n257, &c.n65_dT128, &c.n65_dT256, &c.n129_dT256}) {
    ASSERT_RAN(*r);
    ASSERT_NEAR(r->records.back().T, 0.75, 1e-12);
  }
  {
    SCOPED_TRACE("(a) dT = h");
    const StepRecord &a = c.n65.records.back(), &b = c.n129.records.back(),
                     &d = c.n257.records.back();
    std::cout << "Grid convergence at T = 0.75, dT = h\n";
    const std::array<std::string, 3> grids{"65", "129", "257"};
    report_order("conv", "h_center", grids, a, b, d, &StepRecord::h_center);
    report_order("conv", "force", grids, a, b, d, &StepRecord::force);
    const double order_D = report_order("conv", "Delta", grids, a, b, d, &StepRecord::Delta);
    // With dT = h the space and time errors have opposite signs and partly
    // cancel (space: +0.21e-3 in h_center from 65^2 to 129^2; time: about
    // -0.15e-3), so an order computed from these differences says little; the
    // orders are asserted in (b) and (c).  What must hold here: Delta, whose
    // error is dominated by the time integration, converges at second order,
    // and the differences of h_center shrink.
    EXPECT_GE(order_D, 1.5);
    EXPECT_LE(order_D, 2.6);
    EXPECT_LT(std::abs(d.h_center - b.h_center), std::abs(b.h_center - a.h_center));
  }
  {
    SCOPED_TRACE("(b) space at fixed dT = 3/256");
    const StepRecord &a = c.n65_dT256.records.back(), &b = c.n129_dT256.records.back(),
                     &d = c.n257.records.back();
    std::cout << "Space convergence at T = 0.75, dT = 3/256 on 65^2, 129^2, 257^2\n";
    const std::array<std::string, 3> grids{"65", "129", "257"};
    const double order_h = report_order("space", "h_center", grids, a, b, d, &StepRecord::h_center);
    const double order_F = report_order("space", "force", grids, a, b, d, &StepRecord::force);
    const double order_p = report_order("space", "p_center", grids, a, b, d, &StepRecord::p_center);
    // Second order: 1.8 - 2.2 (measured 1.97 - 2.00).
    for (double order : {order_h, order_F, order_p}) {
      EXPECT_GE(order, 1.8);
      EXPECT_LE(order, 2.2);
    }
  }
  {
    SCOPED_TRACE("(c) time on 65^2");
    const StepRecord &a = c.n65.records.back(), &b = c.n65_dT128.records.back(),
                     &d = c.n65_dT256.records.back();
    std::cout << "Time convergence at T = 0.75 on 65^2, dT = 3/64, 3/128, 3/256\n";
    const std::array<std::string, 3> steps{"dT64", "dT128", "dT256"};
    const double order_D = report_order("time", "Delta", steps, a, b, d, &StepRecord::Delta);
    const double order_F = report_order("time", "force", steps, a, b, d, &StepRecord::force);
    const double order_h = report_order("time", "h_center", steps, a, b, d, &StepRecord::h_center);
    EXPECT_GE(order_D, 1.5) << "separation: " << a.Delta << ", " << b.Delta << ", " << d.Delta
                            << " (first order: the first step loses the T = 0 film force)";
    EXPECT_LE(order_D, 2.6);
    // The force and the central film follow (measured 1.87 and 1.85).
    for (double order : {order_F, order_h}) {
      EXPECT_GE(order, 1.5);
      EXPECT_LE(order, 2.6);
    }
  }
}

// ========================================= 7. FFT vs direct deformation

// The FFT (zero-padded, exact linear convolution) and the direct sum compute
// the same deformation up to round-off (~1e-15 relative); through the whole
// nonlinear solver the time series must agree to ~1e-9 (the iterations take the
// same path; round-off is all that differs).  33^2 through dry contact (T = 1.5).
namespace {

/// A run that also keeps its state after every `every`-th step (the checkpoints).
RunResult run_keeping_states(const ImpactConfig& cfg, int every, std::vector<ImpactState>& states) {
  RunResult out;
  ImpactProblem problem(cfg);
  problem.set_state_sink(every, [&](const ImpactState& s) { states.push_back(s); });
  Recorder recorder(out);
  out.summary = problem.run(recorder);
  return out;
}

/// The run of `cfg` restarted from `state`.
RunResult run_restarted(const ImpactConfig& cfg, const ImpactState& state) {
  RunResult out;
  ImpactProblem problem(cfg);
  problem.restart_from(state);
  Recorder recorder(out);
  out.summary = problem.run(recorder);
  return out;
}

}  // namespace

TEST(ImpactRestart, ContinuesExactlyWhereTheCheckpointWasTaken) {
  // A restart from the state after step k must give the steps after k of the
  // uninterrupted run: the BDF2 history, the extrapolated start, the force
  // extrapolation and the running summary all come from the state.  Contact
  // steps (T > 1) on 65^2; the arithmetic is the same, so are the bits.
  ImpactConfig cfg = moes_config(65);
  cfg.T_end = 3.0;
  constexpr int kEvery = 25;
  std::vector<ImpactState> states;
  const RunResult full = run_keeping_states(cfg, kEvery, states);
  ASSERT_GE(states.size(), 2u);
  const ImpactState& state = states[1];  // after step 50, T = 2.34: in contact
  ASSERT_EQ(state.step, 2 * kEvery);
  ASSERT_GT(state.ball.T, 1.0);
  const RunResult resumed = run_restarted(cfg, state);
  ASSERT_EQ(resumed.records.size() + state.step, full.records.size());
  ASSERT_EQ(resumed.records.front().step, state.step + 1);
  for (std::size_t k = 0; k < resumed.records.size(); ++k) {
    const StepRecord& a = full.records[state.step + k];
    const StepRecord& b = resumed.records[k];
    EXPECT_EQ(a.cycles, b.cycles) << "step " << b.step;
    EXPECT_EQ(a.Delta, b.Delta) << "step " << b.step;
    EXPECT_EQ(a.force, b.force) << "step " << b.step;
    EXPECT_EQ(a.p_max, b.p_max) << "step " << b.step;
    EXPECT_EQ(a.residual, b.residual) << "step " << b.step;
  }
  EXPECT_EQ(resumed.summary.impulse, full.summary.impulse);
  EXPECT_EQ(resumed.summary.edge_impulse, full.summary.edge_impulse);
  EXPECT_EQ(resumed.summary.max_force, full.summary.max_force);  // reached before the restart
  EXPECT_EQ(resumed.summary.steps, full.summary.steps);

  ImpactState wrong = state;
  wrong.P = Field(Grid2D(33, cfg.half_width));
  ImpactProblem problem(cfg);
  EXPECT_THROW(problem.restart_from(wrong), std::invalid_argument);
}

namespace {
/// Expects the steps of `resumed`, a restart after step `from` of `full`, to
/// repeat those of `full` to the bit: their attempts, cycles, Delta and residual.
void expect_steps_repeated(const RunResult& full, const RunResult& resumed, int from) {
  ASSERT_EQ(resumed.records.size() + from, full.records.size());
  for (std::size_t k = 0; k < resumed.records.size(); ++k) {
    const StepRecord& a = full.records[from + k];
    const StepRecord& b = resumed.records[k];
    ASSERT_EQ(a.attempts, b.attempts) << "step " << b.step;
    ASSERT_EQ(a.cycles, b.cycles) << "step " << b.step;
    ASSERT_EQ(a.Delta, b.Delta) << "step " << b.step;
    ASSERT_EQ(a.residual, b.residual) << "step " << b.step;
  }
}
}  // namespace

TEST(ImpactRestart, ContinuesWithTheAttemptTheStepsBeforeNeeded) {
  // M = 20, L = 20 on 65^2 retries steps of its rebound, so some step ends
  // with a damped attempt as the next one's first (AttemptMemory).  A restart
  // from there must begin where the uninterrupted run began: the memory is
  // part of the state (without it the resumed steps take other iterates).
  ImpactConfig cfg = moes_config(65, 20.0, 20.0);
  std::vector<ImpactState> states;
  const RunResult full = run_keeping_states(cfg, 1, states);
  const auto damped = std::find_if(states.begin(), states.end(),
                                   [](const ImpactState& s) { return s.attempts.first > 0; });
  ASSERT_NE(damped, states.end()) << "no step began with a retry's damping";
  const RunResult resumed = run_restarted(cfg, *damped);
  expect_steps_repeated(full, resumed, damped->step);
  EXPECT_EQ(resumed.summary.retried_steps, full.summary.retried_steps);
  EXPECT_EQ(resumed.summary.rebound_speed, full.summary.rebound_speed);
}

TEST(ImpactRestart, ContinuesInTheHalvesTheStepsBeforeNeeded) {
  // With two cycles per attempt the steps of the 33^2 rebound from T = 2.6
  // on fail whole and converge in halves or quarters, so steps begin in
  // halves (SplitMemory).  A restart from there must begin as the
  // uninterrupted run began: the memory is part of the state.
  ImpactConfig cfg = moes_config(33);
  cfg.max_cycles = 2;
  std::vector<ImpactState> states;
  const RunResult full = run_keeping_states(cfg, 1, states);
  ASSERT_RAN(full);
  EXPECT_EQ(full.summary.unconverged_steps, 0);
  const auto halved = std::find_if(states.begin(), states.end(),
                                   [](const ImpactState& s) { return s.splits.begin.first > 0; });
  ASSERT_NE(halved, states.end()) << "no step began in halves";
  const RunResult resumed = run_restarted(cfg, *halved);
  expect_steps_repeated(full, resumed, halved->step);
  EXPECT_EQ(resumed.summary.rebound_speed, full.summary.rebound_speed);

  // Without the memory the resumed run tries its next step whole again.
  ImpactState forgotten = *halved;
  forgotten.splits = {};
  const RunResult whole_first = run_restarted(cfg, forgotten);
  ASSERT_FALSE(whole_first.records.empty());
  EXPECT_GT(whole_first.records.front().attempts, full.records[halved->step].attempts);
}

TEST(ImpactHalvedSteps, AStepNoAttemptSolvesIsSolvedInHalvesOnTheSameTimeGrid) {
  // M = 1000, L = 20 on 65^2: the step to T = 0.8906, where the film first
  // carries the load (p_max 0.015 -> 0.12), converges in none of its four
  // attempts and is solved as two halves (docs/model.md, section 8).  The run
  // must stay on the dT grid, converge every step, keep second order in time
  // across the halved step, and restart across it to the bit.
  ImpactConfig cfg = moes_config(65, 1000.0, 20.0);
  cfg.T_end = 0.95;
  // With the local Newton step after each cycle no step of this case needs
  // halving any more: the halving is tested on the relaxation alone.
  cfg.local_newton_half_width = 0;
  constexpr int kAttemptsOfAWholeStep = 4;  // the first attempt and kMaxRetries = 3 retries
  constexpr int kStateStep = 15;
  std::vector<ImpactState> states;
  const RunResult run = run_keeping_states(cfg, kStateStep, states);
  ASSERT_RAN(run);
  const double dT = run.grid.h();
  std::vector<std::size_t> halved;
  for (std::size_t k = 0; k < run.records.size(); ++k) {
    const StepRecord& r = run.records[k];
    EXPECT_NEAR(r.T, static_cast<double>(k + 1) * dT, 1e-12) << "step " << r.step;
    EXPECT_LE(r.residual, cfg.tolerance) << "step " << r.step;
    if (r.attempts > kAttemptsOfAWholeStep) halved.push_back(k);
  }
  ASSERT_EQ(halved.size(), 1u) << "the case no longer needs a halved step: choose another";
  const std::size_t h = halved.front();
  ASSERT_GT(h, static_cast<std::size_t>(kStateStep));
  ASSERT_LT(h + 1, run.records.size());
  EXPECT_EQ(run.summary.unconverged_steps, 0);

  // Second order in time across the halved step: against a run with dT/4, the
  // error of Delta at the halved step lies between its whole neighbours',
  // widened by half their difference; a first-order step would stand out by
  // O(dT^2) (measured: 9.2e-7 between 4.0e-7 and 3.5e-6, the error rising
  // through zero; with the residual measure alone as stopping rule, -8.8e-6
  // against -7.7e-6 and -8.2e-6, mostly the error of the iteration).
  ImpactConfig fine_cfg = cfg;
  fine_cfg.dT = dT / 4;
  const RunResult fine = run_case(fine_cfg);
  ASSERT_RAN(fine);
  const auto error_at = [&](std::size_t k) {
    const StepRecord& f = fine.records.at(4 * k + 3);
    EXPECT_NEAR(f.T, run.records[k].T, 1e-12);
    return run.records[k].Delta - f.Delta;
  };
  const double before = error_at(h - 1), at = error_at(h), after = error_at(h + 1);
  report("halved_step_Delta_error_before", before);
  report("halved_step_Delta_error_after", after);
  EXPECT_GT(at, std::min(before, after) - 0.5 * std::abs(after - before));
  EXPECT_LT(at, std::max(before, after) + 0.5 * std::abs(after - before));

  // A restart before the halved step repeats it to the bit.
  ASSERT_FALSE(states.empty());
  const RunResult resumed = run_restarted(cfg, states.front());
  ASSERT_EQ(resumed.records.size() + kStateStep, run.records.size());
  for (std::size_t k = 0; k < resumed.records.size(); ++k) {
    const StepRecord &a = run.records[kStateStep + k], &b = resumed.records[k];
    EXPECT_EQ(a.attempts, b.attempts) << "step " << b.step;
    EXPECT_EQ(a.Delta, b.Delta) << "step " << b.step;
    EXPECT_EQ(a.force, b.force) << "step " << b.step;
    EXPECT_EQ(a.p_max, b.p_max) << "step " << b.step;
  }
  report("halved_step_T", run.records[h].T);
  report("halved_step_attempts", run.records[h].attempts);
  report("halved_step_Delta_error_vs_dT_over_4", error_at(h), 3);
}

namespace {

/// Every cycle report of a run, and its steps.
class CycleLog final : public ImpactObserver {
 public:
  void on_cycle(const CycleRecord& c) override { cycles.push_back(c); }
  void on_initial_cycle(int cycle, double residual) override {
    initial.push_back({cycle, residual});
    EXPECT_TRUE(cycles.empty()) << "the solve at T = 0 comes before the steps";
  }
  void on_step(const StepRecord& r, const Field&, const Field&, bool) override {
    steps.push_back(r);
  }
  std::vector<CycleRecord> cycles;
  std::vector<StepRecord> steps;
  std::vector<std::pair<int, double>> initial;  ///< (cycle, residual before it) at T = 0
};

}  // namespace

// In the rebound the spike ring runs inward with the receding contact, 0.6 of a
// mesh per step; the starts of the fixed frame leave its error, the start in
// the contracting frame follows it (PressurePredictor.hpp).  65^2 to lift-off:
// the starts of the rebound and the collapse have half the residual, the steps
// take fewer cycles, and the run ends as without it.
TEST(ImpactConvergence, TheContractingStartHalvesTheStartResidualOfTheRebound) {
  ImpactConfig cfg = moes_config(65);
  const auto run_logged = [](const ImpactConfig& c, CycleLog& log) {
    ImpactProblem problem(c);
    return problem.run(log);
  };
  CycleLog with, without;
  const RunSummary contracting = run_logged(cfg, with);
  cfg.contracting_start = false;
  const RunSummary fixed = run_logged(cfg, without);
  constexpr double kReboundFrom = 2.75;                   // bench_phases.py's phases
  const auto start_residual = [&](const CycleLog& log) {  // geometric mean over the steps
    double log_sum = 0.0;
    int steps = 0;
    for (const CycleRecord& c : log.cycles) {
      // (A start of P = 0, in the last steps before lift-off, has no residual.)
      if (c.T <= kReboundFrom || c.attempt != 0 || c.cycle != 0 || c.residual == 0.0) continue;
      log_sum += std::log(c.residual);
      ++steps;
    }
    return std::exp(log_sum / steps);
  };
  const auto cycles = [&](const CycleLog& log) {
    int total = 0;
    for (const StepRecord& r : log.steps) total += r.T > kReboundFrom ? r.cycles : 0;
    return total;
  };
  report("rebound_start_residual_65_contracting", start_residual(with));
  report("rebound_start_residual_65_fixed", start_residual(without));
  report("rebound_cycles_65_contracting", cycles(with));
  report("rebound_cycles_65_fixed", cycles(without));
  EXPECT_LT(start_residual(with), 0.6 * start_residual(without));
  EXPECT_LT(cycles(with), cycles(without));
  ASSERT_TRUE(contracting.lifted_off && fixed.lifted_off);
  EXPECT_EQ(contracting.T_lift_off, fixed.T_lift_off);
  EXPECT_NEAR(contracting.rebound_speed, fixed.rebound_speed, 1e-5);
  EXPECT_NEAR(contracting.max_force, fixed.max_force, 1e-5);
}

// The solve at T = 0 reports its cycles (the thread budget samples the
// machine there: io/ThreadBudget.hpp), numbered from 1, before any step's.
TEST(ImpactCycles, TheCyclesOfTheSolveAtTZeroAreReportedFirst) {
  ImpactConfig cfg = moes_config(33);
  cfg.T_end = 0.1;
  CycleLog log;
  ImpactProblem problem(cfg);
  problem.run(log);
  ASSERT_FALSE(log.initial.empty());
  for (std::size_t k = 0; k < log.initial.size(); ++k) {
    EXPECT_EQ(log.initial[k].first, static_cast<int>(k) + 1);
    EXPECT_GT(log.initial[k].second, 0.0);
  }
  EXPECT_FALSE(log.cycles.empty());
}

TEST(ImpactCycles, EveryAttemptAndCycleOfEveryIntervalIsReported) {
  // convergence.csv's rows (RunOutput::on_cycle): the case of the halved step
  // above, where attempts fail and an interval is solved in halves.
  ImpactConfig cfg = moes_config(65, 1000.0, 20.0);
  cfg.T_end = 0.95;
  CycleLog log;
  ImpactProblem problem(cfg);
  problem.run(log);
  ASSERT_FALSE(log.steps.empty());
  const double dT = log.steps.front().T;
  for (const StepRecord& r : log.steps) {
    std::vector<const CycleRecord*> mine;
    for (const CycleRecord& c : log.cycles)
      if (c.step == r.step) mine.push_back(&c);
    ASSERT_FALSE(mine.empty()) << "step " << r.step;
    // An attempt starts with cycle 0; the cycles of an attempt count up by one.
    const auto attempts =
        std::count_if(mine.begin(), mine.end(), [](const CycleRecord* c) { return c->cycle == 0; });
    EXPECT_EQ(attempts, r.attempts) << "step " << r.step;
    for (std::size_t k = 1; k < mine.size(); ++k) {
      if (mine[k]->cycle != 0) {
        EXPECT_EQ(mine[k]->cycle, mine[k - 1]->cycle + 1);
      }
    }
    const CycleRecord& last = *mine.back();
    EXPECT_NEAR(last.T, r.T, 1e-12) << "step " << r.step;
    if (r.attempts > 4) {
      // Halved: the last interval is the second half of the step.
      EXPECT_NEAR(last.dt, 0.5 * dT, 1e-12) << "step " << r.step;
    } else {
      EXPECT_NEAR(last.dt, dT, 1e-12) << "step " << r.step;
      EXPECT_EQ(last.residual, r.residual) << "step " << r.step;  // the kept iterate's
      EXPECT_EQ(last.damping, r.attempts == 1 ? 1.0 : cfg.retry_damping) << "step " << r.step;
    }
  }
}

TEST(ImpactDeformation, FftAndDirectGiveTheSameImpact) {
  ImpactConfig cfg = moes_config(33);
  cfg.T_end = 1.5;
  const RunResult fft = run_case(cfg);
  cfg.deformation = DeformationMethod::Direct;
  const RunResult direct = run_case(cfg);
  ASSERT_RAN(fft);
  ASSERT_RAN(direct);
  ASSERT_EQ(fft.records.size(), direct.records.size());
  double worst = 0.0;
  for (std::size_t k = 0; k < fft.records.size(); ++k) {
    const StepRecord &a = fft.records[k], &b = direct.records[k];
    for (auto [x, y] : {std::pair{a.Delta, b.Delta}, std::pair{a.dDelta_dT, b.dDelta_dT},
                        std::pair{a.force, b.force}, std::pair{a.h_center, b.h_center},
                        std::pair{a.h_min, b.h_min}, std::pair{a.p_center, b.p_center},
                        std::pair{a.p_max, b.p_max}}) {
      const double diff = std::abs(x - y) / std::max(1.0, std::abs(x));
      worst = std::max(worst, diff);
      EXPECT_LT(diff, 1e-9) << "step " << a.step;
    }
    // Same path: a 1e-15 perturbation moves a residual across the tolerance
    // only by an extraordinary coincidence.
    EXPECT_EQ(a.cycles, b.cycles) << "step " << a.step;
  }
  double field_diff = 0.0;
  for (std::size_t k = 0; k < fft.last_P.size(); ++k)
    field_diff = std::max(field_diff, std::abs(fft.last_P[k] - direct.last_P[k]));
  EXPECT_LT(field_diff, 1e-9);
  report("fft_vs_direct_max_diff", worst, 3);
  report("fft_vs_direct_final_P_field_max_diff", field_diff, 3);
  report("fft_vs_direct_p_max_final", fft.records.back().p_max);
}

/// The default case (M = 100) at L = 10, or isoviscous at L = 0, on 65^2,
/// with the deformation recomputed once per sweep where the relaxation allows
/// it, or before each colour.
struct UpdateComparison {
  RunResult per_sweep, per_colour;
  double cycle_ratio = 0.0, work_ratio = 0.0;  ///< per sweep / per colour
};
UpdateComparison compare_deformation_updates(double L) {
  ImpactConfig cfg = moes_config(65, 100.0, L);
  UpdateComparison c;
  cfg.relaxation.deformation_each_colour = false;
  c.per_sweep = run_case(cfg);
  cfg.relaxation.deformation_each_colour = true;
  c.per_colour = run_case(cfg);
  double cycles[2] = {0.0, 0.0}, work[2] = {0.0, 0.0};
  for (int run = 0; run < 2; ++run) {
    for (const StepRecord& r : (run == 0 ? c.per_sweep : c.per_colour).records) {
      cycles[run] += r.cycles;
      work[run] += r.work;
    }
  }
  c.cycle_ratio = cycles[0] / cycles[1];
  c.work_ratio = work[0] / work[1];
  return c;
}

TEST(ImpactDeformation, OneUpdatePerSweepGivesTheImpactOfOnePerColour) {
  // The relaxation may recompute the deformation once per zebra sweep instead
  // of before each colour: the second colour then sees the first colour's
  // elastic effect one sweep late.  The iteration still converges to the same
  // discrete solution: the histories agree to the tolerance of the
  // iteration, with the same cycles per step and about half the work.
  const UpdateComparison c = compare_deformation_updates(10.0);
  ASSERT_RAN(c.per_sweep);
  ASSERT_RAN(c.per_colour);
  ASSERT_TRUE(c.per_sweep.summary.lifted_off);
  EXPECT_EQ(c.per_sweep.summary.T_lift_off, c.per_colour.summary.T_lift_off);
  // Measured 1e-6 and 3e-6 on 129^2 and 257^2 (docs/performance.md).
  EXPECT_NEAR(c.per_sweep.summary.rebound_speed, c.per_colour.summary.rebound_speed, 2e-5);
  EXPECT_NEAR(c.per_sweep.summary.max_force, c.per_colour.summary.max_force, 1e-4);
  EXPECT_LE(c.cycle_ratio, 1.05);
  EXPECT_LT(c.work_ratio, 0.7);
  EXPECT_EQ(c.per_sweep.summary.unconverged_steps, 0);
  report("per_sweep_over_per_colour_cycles", c.cycle_ratio, 3);
  report("per_sweep_over_per_colour_work", c.work_ratio, 3);
}

TEST(ImpactMultigrid, TheCoarseLevelsFaceMeanChangesTheWorkNotTheSolution) {
  // The coarse levels of FAS only carry corrections to the finest grid's
  // solution, so their operator may differ from the finest one's.  Across the
  // spike, where xi = H^3 / eta jumps by orders of magnitude between coarse
  // points, the logarithmic mean is the exact Barus flux and the arithmetic
  // one overestimates it many times (FaceMean.LogarithmicMeanIsTheExactBarus
  // Flux).  With the logarithmic mean on the coarse levels only, a strongly
  // piezoviscous case converges to the same solution with less work.
  ImpactConfig cfg = moes_config(65, 100.0, 40.0);
  const RunResult same = run_case(cfg);
  cfg.coarse_face_mean = FaceMean::Logarithmic;
  const RunResult logarithmic = run_case(cfg);
  ASSERT_RAN(same);
  ASSERT_RAN(logarithmic);
  ASSERT_TRUE(same.summary.lifted_off);
  ASSERT_TRUE(logarithmic.summary.lifted_off);
  const auto work = [](const RunResult& run) {
    double sum = 0.0;
    for (const StepRecord& r : run.records) sum += r.work;
    return sum;
  };
  const double work_ratio = work(logarithmic) / work(same);
  report("coarse_logarithmic_over_same_work_65_L40", work_ratio, 3);
  report("coarse_logarithmic_rebound_speed_change",
         logarithmic.summary.rebound_speed - same.summary.rebound_speed, 3);
  EXPECT_NEAR(logarithmic.summary.T_lift_off, same.summary.T_lift_off,
              1.01 * effective_time_step(cfg));
  // Both iterations stop at the tolerance, from other iterates: measured
  // 1.6e-5 here, 3e-7 to 2.7e-5 on 65^2 and 129^2 at L = 20, 30 and 40.
  EXPECT_NEAR(logarithmic.summary.rebound_speed, same.summary.rebound_speed, 5e-5);
  EXPECT_NEAR(logarithmic.summary.max_force, same.summary.max_force, 1e-4);
  // Measured 0.87 (129^2: 0.85; 257^2 at L = 30: 0.73; docs/performance.md).
  EXPECT_LT(work_ratio, 0.95);
}

TEST(ImpactDeformation, IsoviscousContactKeepsTheUpdateItNeeds) {
  // At L = 0 most points of the contact are Gauss-Seidel points whose elastic
  // term is comparable to the flow term; once per sweep everywhere, 33 of 90
  // steps stalled and were retried (2.3 times the work).  The relaxation
  // recomputes the deformation for the second colour where such points
  // outnumber the distributive ones, and the run costs less than before.
  const UpdateComparison c = compare_deformation_updates(0.0);
  ASSERT_RAN(c.per_sweep);
  ASSERT_RAN(c.per_colour);
  ASSERT_TRUE(c.per_sweep.summary.lifted_off);
  EXPECT_EQ(c.per_sweep.summary.retried_steps, 0);
  EXPECT_EQ(c.per_sweep.summary.T_lift_off, c.per_colour.summary.T_lift_off);
  EXPECT_NEAR(c.per_sweep.summary.rebound_speed, c.per_colour.summary.rebound_speed, 2e-5);
  EXPECT_LT(c.work_ratio, 1.0);
  report("isoviscous_per_sweep_over_per_colour_work", c.work_ratio, 3);
}

TEST(ImpactSymmetry, QuadrantRunEqualsTheFullDomainRun) {
  // The default case is even in X and Y, so the quadrant with mirror
  // conditions must give the full domain's run to rounding: the same cycles
  // and histories, step by step, to lift-off on 65^2.  Rounding can tip a
  // residual across the tolerance and change a step's cycle count (measured:
  // step 88 of 90, in the collapse of the pocket); from there on the two runs
  // agree to the tolerance of the iteration only.  Without the local Newton
  // step: on the full domain its window lies around one of the four images
  // of the largest residual, on the quadrant around their folded corner, and
  // the two solve different local problems (the next test).
  ImpactConfig cfg = moes_config(65);
  cfg.local_newton_half_width = 0;
  const RunResult quadrant = run_case(cfg);
  cfg.use_symmetry = false;
  const RunResult full = run_case(cfg);
  ASSERT_RAN(quadrant);
  ASSERT_RAN(full);
  ASSERT_TRUE(quadrant.summary.lifted_off);
  ASSERT_EQ(quadrant.records.size(), full.records.size());
  EXPECT_EQ(quadrant.grid.n, full.grid.n);
  std::size_t same_path = 0;
  while (same_path < full.records.size() &&
         quadrant.records[same_path].cycles == full.records[same_path].cycles)
    ++same_path;
  EXPECT_GE(same_path, full.records.size() * 9 / 10);
  double worst = 0.0;
  std::size_t beyond_rounding = 0;
  for (std::size_t k = 0; k < same_path; ++k) {
    const StepRecord &a = quadrant.records[k], &b = full.records[k];
    double step_worst = 0.0;
    for (auto [x, y] : {std::pair{a.Delta, b.Delta}, std::pair{a.dDelta_dT, b.dDelta_dT},
                        std::pair{a.force, b.force}, std::pair{a.h_center, b.h_center},
                        std::pair{a.h_min, b.h_min}, std::pair{a.p_center, b.p_center},
                        std::pair{a.p_max, b.p_max}}) {
      step_worst = std::max(step_worst, std::abs(x - y) / std::max(1.0, std::abs(x)));
    }
    worst = std::max(worst, step_worst);
    if (step_worst >= 1e-7) ++beyond_rounding;
  }
  // The DCT and the full FFT differ by 1e-12 per evaluation, and each step's
  // iteration carries such differences on: 9.4e-9 at most when the
  // deformation was recomputed before each colour.  Once per sweep, where the
  // relaxation allows it, a rounding difference can tip that choice for a
  // sweep (an integer comparison of point counts), and such a step agrees to
  // the tolerance of the iteration only: measured 3 of 90 steps, all in the
  // collapse of the pocket, the largest 8.6e-5.
  EXPECT_LE(beyond_rounding, full.records.size() / 20);
  EXPECT_LT(worst, 1e-3);
  EXPECT_EQ(quadrant.summary.T_lift_off, full.summary.T_lift_off);
  EXPECT_NEAR(quadrant.summary.rebound_speed, full.summary.rebound_speed, 1e-6);
  EXPECT_NEAR(quadrant.summary.max_force, full.summary.max_force, 1e-9);
  double field_diff = 0.0;
  for (std::size_t k = 0; k < full.last_H.size(); ++k)
    field_diff = std::max(field_diff, std::abs(quadrant.last_H[k] - full.last_H[k]));
  EXPECT_LT(field_diff, 1e-6);
  report("quadrant_vs_full_steps_on_the_same_path", static_cast<double>(same_path));
  report("quadrant_vs_full_max_diff_on_the_same_path", worst, 3);
  report("quadrant_vs_full_steps_beyond_rounding", static_cast<double>(beyond_rounding));
  report("quadrant_vs_full_final_H_max_diff", field_diff, 3);
}

TEST(ImpactSymmetry, QuadrantAndFullDomainAgreeToTheToleranceWithTheLocalNewtonStep) {
  // With the local Newton step (the default) the quadrant and the full domain
  // solve different windows, so their iterates differ by what the tolerance
  // leaves, not by rounding: the outcome must be the same physics (docs/
  // performance.md, the targets of issue 9: lift-off within one step, rebound
  // speed and maximum force within 1e-4).
  ImpactConfig cfg = moes_config(65);
  ASSERT_GT(cfg.local_newton_half_width, 0);
  const RunResult quadrant = run_case(cfg);
  cfg.use_symmetry = false;
  const RunResult full = run_case(cfg);
  ASSERT_RAN(quadrant);
  ASSERT_RAN(full);
  ASSERT_TRUE(quadrant.summary.lifted_off);
  ASSERT_TRUE(full.summary.lifted_off);
  EXPECT_NEAR(quadrant.summary.T_lift_off, full.summary.T_lift_off, 1.01 * quadrant.grid.h());
  EXPECT_NEAR(quadrant.summary.rebound_speed, full.summary.rebound_speed, 1e-4);
  EXPECT_NEAR(quadrant.summary.max_force, full.summary.max_force, 1e-4);
  EXPECT_EQ(quadrant.summary.unconverged_steps, 0);
  EXPECT_EQ(full.summary.unconverged_steps, 0);
  report("quadrant_vs_full_local_newton_rebound_speed_diff",
         std::abs(quadrant.summary.rebound_speed - full.summary.rebound_speed), 3);
}

// Each window of a local Newton step lowers its own residual, but together,
// with the Delta of their force, they can leave the grid worse: such a step is
// taken back.  Without that, M = 20, L = 20 on 129^2 with two windows lost the
// pocket collapse at T = 3.773 (every attempt stalled at 1e-2: exit 1).
TEST(ImpactLocalNewton, AStepThatRaisesTheResidualIsTakenBack) {
  ImpactConfig cfg = moes_config(129, 20.0, 20.0);
  cfg.local_newton_windows = 2;
  const RunResult run = run_case(cfg);
  ASSERT_RAN(run);
  EXPECT_TRUE(run.summary.lifted_off);
  EXPECT_EQ(run.summary.unconverged_steps, 0);
}

// ---------------------------------------------------------------------------
// When an attempt of a time step stops cycling (impact/AttemptPolicy.hpp).

namespace {
/// Residuals after cycles 1..cycles of an attempt that falls by `rate` per cycle from `first`.
std::vector<double> geometric_history(double first, double rate, int cycles) {
  std::vector<double> history;
  for (int c = 0; c < cycles; ++c) history.push_back(first * std::pow(rate, c));
  return history;
}
constexpr double kTolerance = 1e-5;
constexpr int kMaxCycles = 20;
}  // namespace

TEST(AttemptPolicy, EndsAConvergedAttemptAtOnce) {
  std::vector<double> history = geometric_history(1e-1, 0.5, 5);
  history.push_back(0.9 * kTolerance);
  EXPECT_EQ(judge_attempt(history, kTolerance, kMaxCycles), AttemptVerdict::Converged);
}

TEST(AttemptPolicy, CyclesOnBelowTheToleranceWhileTheForceMoves) {
  // The residual measure hardly sees a smooth error: an attempt below the
  // tolerance whose last cycle still moved the force goes on, up to max_cycles.
  std::vector<double> history = geometric_history(1e-1, 0.5, 5);
  history.push_back(0.9 * kTolerance);
  EXPECT_EQ(judge_attempt(history, kTolerance, kMaxCycles, false), AttemptVerdict::Continue);
  EXPECT_EQ(judge_attempt(history, kTolerance, kMaxCycles, true), AttemptVerdict::Converged);
  const std::vector<double> at_max = geometric_history(1e-3, 0.5, kMaxCycles);
  ASSERT_LT(at_max.back(), kTolerance);
  EXPECT_EQ(judge_attempt(at_max, kTolerance, kMaxCycles, false), AttemptVerdict::Converged);
  // Above the tolerance the force does not end an attempt.
  const std::vector<double> above = geometric_history(1e-1, 0.5, 3);
  EXPECT_EQ(judge_attempt(above, kTolerance, kMaxCycles, true), AttemptVerdict::Continue);
}

TEST(AttemptPolicy, CyclesOnWhileBelowMaxCycles) {
  const std::vector<double> slow = geometric_history(1e-1, 0.99, kMaxCycles - 1);
  EXPECT_EQ(judge_attempt(slow, kTolerance, kMaxCycles), AttemptVerdict::Continue);
}

TEST(AttemptPolicy, EndsAnAttemptThatClimbsFarAboveItsLowestResidual) {
  // Falls to 1e-3, then climbs: within kLostGroundFactor it may still come
  // back (converged attempts of the 513^2 collapse rose up to 1.14 times),
  // beyond it the attempt is lost.
  std::vector<double> history = {1e-1, 1e-2, 1e-3};
  history.push_back(0.99 * kLostGroundFactor * 1e-3);
  EXPECT_EQ(judge_attempt(history, kTolerance, kMaxCycles), AttemptVerdict::Continue);
  history.push_back(1.01 * kLostGroundFactor * 1e-3);
  EXPECT_EQ(judge_attempt(history, kTolerance, kMaxCycles), AttemptVerdict::LostGround);
}

TEST(AttemptPolicy, ExtendsASteadyAttemptThatWillReachTheTolerance) {
  // 0.69 per cycle, the rate of the 513^2 collapse's converging retries: from
  // 1e-1, 8.7e-5 after 20 cycles; 6 more reach the tolerance.
  const std::vector<double> steady = geometric_history(1e-1, 0.69, kMaxCycles);
  ASSERT_GT(steady.back(), kTolerance);
  EXPECT_EQ(judge_attempt(steady, kTolerance, kMaxCycles), AttemptVerdict::Continue);
}

TEST(AttemptPolicy, DoesNotExtendASlowOrHopelessAttempt) {
  // Steady but too slow for the extension: 0.95 per cycle.
  const std::vector<double> slow = geometric_history(1e-3, 0.95, kMaxCycles);
  EXPECT_EQ(judge_attempt(slow, kTolerance, kMaxCycles), AttemptVerdict::Exhausted);
  // Fast enough (0.85) but too far: 0.18 after 20 cycles would need 60 more.
  const std::vector<double> far = geometric_history(4e0, 0.85, kMaxCycles);
  EXPECT_EQ(judge_attempt(far, kTolerance, kMaxCycles), AttemptVerdict::Exhausted);
  // Every attempt ends at kExtendedCycleFactor times max_cycles.
  const std::vector<double> at_cap = geometric_history(1e2, 0.7, kExtendedCycleFactor * kMaxCycles);
  ASSERT_GT(at_cap.back(), kTolerance);
  EXPECT_EQ(judge_attempt(at_cap, kTolerance, kMaxCycles), AttemptVerdict::Exhausted);
}

TEST(AttemptPolicy, AnUnconvergedIterateWhosePressureVanishedIsNotKept) {
  // A step that began with a film force keeps no unconverged iterate without
  // one: the run would take it for a lift-off (M = 100, L = 20 on 1025^2).
  EXPECT_FALSE(may_keep_unconverged(0.059, 0.0));
  EXPECT_TRUE(may_keep_unconverged(0.059, 1e-12));
  // Without a force at the start there is nothing to lose.
  EXPECT_TRUE(may_keep_unconverged(0.0, 0.0));
}

TEST(AttemptPolicy, EveryStepGetsEveryAttemptBeginningWithTheRememberedOne) {
  // The more damped attempts first, then the lighter ones: a step that
  // begins at the most damped attempt is not split (or kept above the
  // tolerance) before the lighter ones have had their turn.
  EXPECT_EQ(attempt_order(0), (std::vector<int>{0, 1, 2, 3}));
  EXPECT_EQ(attempt_order(1), (std::vector<int>{1, 2, 3, 0}));
  EXPECT_EQ(attempt_order(2), (std::vector<int>{2, 3, 1, 0}));
  EXPECT_EQ(attempt_order(kMaxRetries), (std::vector<int>{3, 2, 1, 0}));
  for (int first = 0; first <= kMaxRetries; ++first)
    EXPECT_EQ(attempt_order(first).size(), static_cast<std::size_t>(kMaxRetries + 1)) << first;
}

// A step that needed a heavier attempt makes it the next step's first; after
// kStepsBeforeLighterAttempt steps solved there the next lighter one is tried.
TEST(AttemptMemory, StartsWhereTheLastStepConvergedAndStepsBackAfterAStreak) {
  AttemptMemory memory;
  memory = remember_attempt(memory, 0);
  EXPECT_EQ(memory.first, 0);  // light steps never leave attempt 0
  EXPECT_EQ(memory.streak, 0);
  memory = remember_attempt(memory, 2);
  EXPECT_EQ(memory.first, 2);
  for (int k = 1; k < kStepsBeforeLighterAttempt; ++k) {
    memory = remember_attempt(memory, 2);
    EXPECT_EQ(memory.first, 2) << k;
    EXPECT_EQ(memory.streak, k);
  }
  memory = remember_attempt(memory, 2);
  EXPECT_EQ(memory.first, 1);
  EXPECT_EQ(memory.streak, 0);
  EXPECT_TRUE(memory.probing);
  memory = remember_attempt(memory, kMaxRetries);  // the lighter one failed again
  EXPECT_EQ(memory.first, kMaxRetries);
  EXPECT_EQ(memory.streak, 0);
  EXPECT_FALSE(memory.probing);
}

// A single step that needed halves leaves the next one whole; two in a row
// make the next begin with the halvings both needed, and from there the
// memory probes the longer interval as AttemptMemory probes the lighter attempt.
TEST(SplitMemory, BeginsInHalvesOnlyAfterTwoStepsThatNeededThem) {
  SplitMemory memory;
  memory = remember_split(memory, 2);  // one step needed quarters
  EXPECT_EQ(memory.begin.first, 0);
  EXPECT_EQ(memory.last_needed, 2);
  memory = remember_split(memory, 0);  // the next converged whole
  EXPECT_EQ(memory.begin.first, 0);
  memory = remember_split(memory, 2);
  memory = remember_split(memory, 1);  // quarters, then halves: both needed halves
  EXPECT_EQ(memory.begin.first, 1);
  memory = remember_split(memory, kMaxSplitDepth + 1);  // beyond the deepest rescue
  EXPECT_EQ(memory.begin.first, 1);                     // the step before needed halves
  EXPECT_EQ(memory.last_needed, kMaxSplitDepth);
  const int deep = kMaxSplitDepth;  // thirty-seconds where sixteenths fail (1025^2, L = 20)
  memory = remember_split(memory, deep);
  EXPECT_EQ(memory.begin.first, deep);
  for (int k = 1; k < kStepsBeforeLighterAttempt; ++k) {
    memory = remember_split(memory, deep);
    EXPECT_EQ(memory.begin.first, deep) << k;
  }
  memory = remember_split(memory, deep);
  EXPECT_EQ(memory.begin.first, deep - 1);  // the probe of the longer interval
  EXPECT_TRUE(memory.begin.probing);
  memory = remember_split(memory, deep - 1);  // it converged
  EXPECT_EQ(memory.begin.first, deep - 1);
  EXPECT_FALSE(memory.begin.probing);
  EXPECT_EQ(memory.begin.failed_probes, 0);
}

namespace {
/// The steps solved in attempt `hard` until the memory probes the lighter one,
/// from a memory that starts there.
int steps_until_probe(AttemptMemory& memory, int hard) {
  int steps = 0;
  while (memory.first == hard) {
    memory = remember_attempt(memory, hard);
    ++steps;
  }
  return steps;
}
}  // namespace

// Probes that fail one after the other come ever more rarely (the pocket
// collapse of 1025^2, where every probe failed); one that succeeds makes the
// next come after kStepsBeforeLighterAttempt steps again.
TEST(AttemptMemory, ProbesThatFailBackOffAndOneThatSucceedsResetsThem) {
  const int hard = 2;
  AttemptMemory memory = remember_attempt({}, hard);
  std::vector<int> intervals;
  for (int probe = 0; probe <= kMaxProbeBackoff + 1; ++probe) {
    intervals.push_back(steps_until_probe(memory, hard));
    ASSERT_TRUE(memory.probing);
    ASSERT_EQ(memory.first, hard - 1);
    memory = remember_attempt(memory, hard);  // the probe failed
    ASSERT_FALSE(memory.probing);
  }
  const int k = kStepsBeforeLighterAttempt;
  EXPECT_EQ(intervals, (std::vector<int>{k, 2 * k, 4 * k, 8 * k, 8 * k}));
  EXPECT_EQ(memory.failed_probes, kMaxProbeBackoff);

  // A step in the attempt it began with that fails is no probe: it keeps the back-off.
  memory = remember_attempt(memory, hard + 1);
  EXPECT_EQ(memory.failed_probes, kMaxProbeBackoff);
  memory = remember_attempt({hard, 0, kMaxProbeBackoff, false}, hard);
  EXPECT_EQ(memory.streak, 1);

  // A probe that converges: the next probe after k steps again.
  memory = {hard - 1, 0, kMaxProbeBackoff, true};
  memory = remember_attempt(memory, hard - 1);
  EXPECT_EQ(memory.failed_probes, 0);
  EXPECT_FALSE(memory.probing);
  EXPECT_EQ(memory.streak, 1);
  EXPECT_EQ(steps_until_probe(memory, hard - 1), k - 1);
  EXPECT_EQ(memory.first, hard - 2);
}

// ---------------------------------------------------------------------------
// The start of a step: the bounded extrapolation in time (PressurePredictor.hpp)

namespace {

/// A field on an n x n full grid with the values of `value(i, j)`.
template <class Value>
Field field_of(int n, Value&& value) {
  Field f(Grid2D(n, 1.0));
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) f(i, j) = value(i, j);
  return f;
}

/// A ridge of height 2 on a level of 1 along the grid column `column`, on an
/// n x n grid: a peak one mesh wide.
Field ridge_at(int n, int column) {
  return field_of(n, [column](int i, int) { return 1.0 + (i == column ? 2.0 : 0.0); });
}

/// The plain linear extrapolation max(0, (1 + omega) last - omega before).
Field plain_extrapolation(const Field& last, const Field& before, double omega) {
  Field out = last;
  for (std::size_t k = 0; k < out.size(); ++k)
    out[k] = std::max(0.0, (1.0 + omega) * last[k] - omega * before[k]);
  return out;
}

}  // namespace

// A pressure that changes alike everywhere keeps the whole extrapolation: the
// bound takes nothing from the second order of the start where P is smooth.
TEST(PressurePredictor, KeepsTheFullExtrapolationOfAChangeAlikeEverywhere) {
  const int n = 17;
  const auto dome = [](int i, int j) { return 2.0 + std::sin(0.4 * i) * std::cos(0.3 * j); };
  const Field before = field_of(n, dome);
  const Field last = field_of(n, [&](int i, int j) { return dome(i, j) + 0.05; });
  for (const double omega : {1.0, 0.5, 2.0}) {
    Field out(Grid2D(n, 1.0));
    bounded_extrapolation(last, before, omega, out);
    const Field plain = plain_extrapolation(last, before, omega);
    for (std::size_t k = 0; k < out.size(); ++k) EXPECT_DOUBLE_EQ(out[k], plain[k]) << k;
  }
}

// A peak one mesh wide that moved by one mesh: plain extrapolation doubles it
// (the rebound's spike on 1025^2 started its steps at 4.97 against 2.75); the
// bounded start stays within the peak's height and is nearer the peak's next
// position than the plain one.
TEST(PressurePredictor, DoesNotDoubleAPeakThatMovesAcrossTheMesh) {
  const int n = 33;
  const Field before = ridge_at(n, 15);
  const Field last = ridge_at(n, 16);
  const Field next = ridge_at(n, 17);
  Field out(Grid2D(n, 1.0));
  bounded_extrapolation(last, before, 1.0, out);
  const Field plain = plain_extrapolation(last, before, 1.0);
  const auto largest = [](const Field& f) {
    return *std::max_element(f.span().begin(), f.span().end());
  };
  EXPECT_DOUBLE_EQ(largest(plain), 5.0);
  EXPECT_DOUBLE_EQ(largest(out), largest(last));
  const auto distance = [&](const Field& f) {
    double sum = 0.0;
    for (std::size_t k = 0; k < f.size(); ++k) sum += (f[k] - next[k]) * (f[k] - next[k]);
    return std::sqrt(sum);
  };
  EXPECT_LT(distance(out), 0.75 * distance(plain));
}

/// The fields of pressure(t, i, j) at t = 0, 1, ..., count - 1 on an n^2 grid.
template <class Pressure>
std::vector<Field> levels_in_time(int n, Pressure pressure, int count) {
  std::vector<Field> levels;
  for (int k = 0; k < count; ++k)
    levels.push_back(
        field_of(n, [&](int i, int j) { return pressure(static_cast<double>(k), i, j); }));
  return levels;
}

// A pressure of degree d = 2 or 3 in time, smooth in space, whose differences
// in time decrease: the series start of order d is exact, the one of order
// d - 1 off by the d-th difference (d! times the leading coefficient).  (A
// ramp in space: at a point that is the largest of its neighbourhood, here the
// corner, the bound, the range widened by the first difference, clips the
// higher differences too.)
TEST(PressurePredictor, SeriesStartIsExactForAPressurePolynomialInTime) {
  const int n = 17;
  const std::array<double, 4> coefficient{2.0, 0.1, 0.02, 0.001};  // of t^0 ... t^3
  const std::array<double, 4> factorial{1.0, 1.0, 2.0, 6.0};
  for (int degree = 2; degree <= 3; ++degree) {
    const std::vector<Field> levels = levels_in_time(
        n,
        [&](double t, int i, int j) {
          double p = 0.3 * i + 0.2 * j;
          for (int k = 0; k <= degree; ++k) p += coefficient[k] * std::pow(t, k);
          return p;
        },
        degree + 2);
    const Field& last = levels[degree];
    const Field& next = levels[degree + 1];
    std::vector<const Field*> earlier;  // the level before `last` first
    for (int k = degree - 1; k >= 0; --k) earlier.push_back(&levels[k]);
    Field exact(Grid2D(n, 1.0));
    Field lower(Grid2D(n, 1.0));
    bounded_series_extrapolation(last, earlier, exact);
    bounded_series_extrapolation(last, std::span(earlier).first(degree - 1), lower);
    const double difference = factorial[degree] * coefficient[degree];
    for (int j = 0; j < n; ++j) {
      for (int i = 0; i < n; ++i) {
        if (i == n - 1 && j == n - 1) continue;  // the corner, the largest of its neighbourhood
        EXPECT_NEAR(exact(i, j), next(i, j), 1e-12) << degree << ' ' << i << ' ' << j;
        EXPECT_NEAR(lower(i, j), next(i, j) - difference, 1e-12) << degree << ' ' << i << ' ' << j;
      }
    }
  }
}

// Where the history is not resolved in time (a peak that moves one mesh per
// step: the second difference as large as the first), a point keeps the
// linear extrapolation, bounds included.
TEST(PressurePredictor, QuadraticStartFallsBackToLinearWhereTheHistoryIsNotResolved) {
  const int n = 33;
  const Field before2 = ridge_at(n, 14);
  const Field before = ridge_at(n, 15);
  const Field last = ridge_at(n, 16);
  Field quadratic(Grid2D(n, 1.0));
  Field linear(Grid2D(n, 1.0));
  const std::array<const Field*, 2> earlier{&before, &before2};
  bounded_series_extrapolation(last, earlier, quadratic);
  bounded_extrapolation(last, before, 1.0, linear);
  for (std::size_t k = 0; k < last.size(); ++k) EXPECT_EQ(quadratic[k], linear[k]) << k;
  const Field other_grid(Grid2D(9, 1.0));
  const std::array<const Field*, 2> mixed{&before, &other_grid};
  EXPECT_THROW(bounded_series_extrapolation(last, mixed, quadratic), std::invalid_argument);
  const std::array<const Field*, 4> too_many{&before, &before2, &before2, &before2};
  EXPECT_THROW(bounded_series_extrapolation(last, too_many, quadratic), std::invalid_argument);
}

// Where the third difference is not smaller than the second, a point keeps
// the quadratic start.
TEST(PressurePredictor, CubicStartFallsBackToQuadraticWhereTheThirdDifferenceIsNotSmaller) {
  const int n = 17;
  const std::vector<Field> levels = levels_in_time(
      n,
      [](double t, int i, int j) {
        return 2.0 + 0.3 * i + 0.2 * j + 0.1 * t + 0.02 * t * t + 0.001 * t * t * t;
      },
      4);
  // Level 0 moved so that the third difference (0.1) exceeds the second (0.052).
  const Field unresolved = field_of(n, [&](int i, int j) { return levels[0](i, j) - 0.094; });
  const std::array<const Field*, 3> with_unresolved{&levels[2], &levels[1], &unresolved};
  const std::array<const Field*, 2> three_levels{&levels[2], &levels[1]};
  Field cubic(Grid2D(n, 1.0));
  Field quadratic(Grid2D(n, 1.0));
  bounded_series_extrapolation(levels[3], with_unresolved, cubic);
  bounded_series_extrapolation(levels[3], three_levels, quadratic);
  for (std::size_t k = 0; k < cubic.size(); ++k) EXPECT_EQ(cubic[k], quadratic[k]) << k;
}

// Whatever the fields, the start is never negative and never leaves the range
// of the last pressure around the point widened by omega times the least
// change in time there; in a new thread count it is the same to the bit.
TEST(PressurePredictor, StaysWithinItsBoundAndNeverNegative) {
  const int n = 65;  // large enough for the loop to run on threads
  unsigned state = 12345u;
  const auto uniform = [&state]() {
    state = state * 1103515245u + 12345u;
    return static_cast<double>((state >> 8) & 0xffffu) / 65536.0;
  };
  const Field before = field_of(n, [&](int, int) { return 3.0 * uniform(); });
  const Field last = field_of(n, [&](int, int) { return 3.0 * uniform(); });
  const double omega = 0.7;
  Field out(Grid2D(n, 1.0));
  bounded_extrapolation(last, before, omega, out);
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      double lowest = last(i, j), highest = last(i, j), change = 1e300;
      for (int b = std::max(0, j - 1); b <= std::min(n - 1, j + 1); ++b)
        for (int a = std::max(0, i - 1); a <= std::min(n - 1, i + 1); ++a) {
          lowest = std::min(lowest, last(a, b));
          highest = std::max(highest, last(a, b));
          change = std::min(change, std::abs(last(a, b) - before(a, b)));
        }
      EXPECT_GE(out(i, j), 0.0);
      EXPECT_GE(out(i, j), std::max(0.0, lowest - omega * change)) << i << ' ' << j;
      EXPECT_LE(out(i, j), highest + omega * change) << i << ' ' << j;
    }
  }
  Field again(Grid2D(n, 1.0));
  const int threads = omp_get_max_threads();
  omp_set_num_threads(2);
  bounded_extrapolation(last, before, omega, again);
  omp_set_num_threads(threads);
  EXPECT_TRUE(std::equal(out.span().begin(), out.span().end(), again.span().begin()));
  EXPECT_THROW(bounded_extrapolation(last, Field(Grid2D(9, 1.0)), omega, again),
               std::invalid_argument);
}

// ---------------------------------------------------------------------------
// The start in a contracting frame (PressurePredictor.hpp)

namespace {

/// A field on `grid` with the values of value(X, Y) at every point.
template <class Value>
Field field_on(const Grid2D& grid, Value&& value) {
  Field f(grid);
  for (int j = 0; j < grid.n; ++j)
    for (int i = 0; i < grid.n; ++i) f(i, j) = value(grid.x(i), grid.y(j));
  return f;
}

/// The quadrant of 129^2 on [-1.5, 1.5]^2, and the full grid of the same mesh.
std::array<Grid2D, 2> quadrant_and_full_grid() { return {Grid2D(65, 1.5, true), Grid2D(129, 1.5)}; }

}  // namespace

// Bilinear interpolation is exact for a field bilinear in X and Y: contracted
// by c, 1 + 0.3 X - 0.2 Y + 0.1 X Y becomes 1 + 0.3 c X - 0.2 c Y + 0.1 c^2 X Y
// wherever (c X, c Y) lies on the grid, and zero beyond it and on the grid's
// outer boundary, where the pressure is held at zero.
TEST(PressurePredictor, ContractionIsExactForABilinearField) {
  const auto bilinear = [](double x, double y, double c) {
    return 1.0 + 0.3 * c * x - 0.2 * c * y + 0.1 * c * c * x * y;
  };
  for (const Grid2D& grid : quadrant_and_full_grid()) {
    const Field field = field_on(grid, [&](double x, double y) { return bilinear(x, y, 1.0); });
    const double lowest = grid.x(0), highest = grid.x(grid.n - 1);
    for (const double c : {0.9, 1.0, 1.1}) {
      Field out(grid);
      contract_radially(grid, field, c, out);
      for (int j = 0; j < grid.n; ++j) {
        for (int i = 0; i < grid.n; ++i) {
          const double x = grid.x(i), y = grid.y(j);
          const bool outer =
              i == grid.n - 1 || j == grid.n - 1 || (!grid.mirrored && (i == 0 || j == 0));
          const auto on_grid = [&](double s) { return s >= lowest && s < highest; };
          const double expected =
              !outer && on_grid(c * x) && on_grid(c * y) ? bilinear(x, y, c) : 0.0;
          EXPECT_NEAR(out(i, j), expected, 1e-12)
              << grid.mirrored << ' ' << c << ' ' << i << ' ' << j;
        }
      }
    }
  }
}

// A ring that shrinks by c per step as its height grows: the contraction that
// maps the level before onto the last is found to a small part of its
// distance from 1, on the quadrant and on the full grid alike.
TEST(PressurePredictor, RadialContractionFindsTheShrinkOfARing) {
  const auto ring = [](double R, double R0) {
    const double w = 0.03;  // 2.6 meshes
    return std::exp(-((R - R0) / w) * ((R - R0) / w));
  };
  for (const Grid2D& grid : quadrant_and_full_grid()) {
    for (const double c : {0.98, 1.0, 1.015, 1.03}) {
      const Field last =
          field_on(grid, [&](double x, double y) { return ring(std::hypot(x, y), 0.6); });
      const Field before = field_on(  // and 5 % lower: the spike grows as it runs inward
          grid, [&](double x, double y) { return 0.95 * ring(std::hypot(x, y) / c, 0.6); });
      EXPECT_NEAR(radial_contraction(grid, last, before), c, 1e-3) << grid.mirrored << ' ' << c;
    }
  }
}

// A pressure bilinear in X / a and Y / a whose size a shrinks by q per step
// while its height grows linearly in time: each earlier level, contracted by
// c^(k+1) with c = 1 / q, is the same bilinear field times a height linear in
// time, which bilinear interpolation and the linear series carry exactly.  So
// the contracting start is the next level to rounding wherever the levels it
// contracts lie on the grid; the linear start of the fixed frame is not.  The
// same bits on one and on two threads.
TEST(PressurePredictor, ContractingStartIsExactForABilinearFieldThatShrinksAsItGrows) {
  const Grid2D grid = Grid2D(129, 1.5, true);  // the quadrant of 257^2: large enough for threads
  const double q = 0.988;                      // 0.6 of a mesh per step at R = 0.6
  const auto level = [&](double t) {
    const double a = 0.6 * std::pow(q, t);
    return field_on(grid, [&](double x, double y) {
      return (1.0 + 0.03 * t) * (2.0 + 0.3 * x / a + 0.2 * y / a + 0.1 * x * y / (a * a));
    });
  };
  const Field next = level(2.0), last = level(1.0), before = level(0.0);
  const std::array<const Field*, 1> earlier{&before};
  Field contracting(grid), fixed(grid);
  contracting_frame_extrapolation(grid, last, earlier, 1.0 / q, contracting);
  bounded_series_extrapolation(last, earlier, fixed);
  const double reach = grid.x(grid.n - 1) * q * q;  // where the level before lies on the grid
  const auto largest_error = [&](const Field& start) {
    double largest = 0.0;
    for (int j = 0; grid.y(j) < reach; ++j)
      for (int i = 0; grid.x(i) < reach; ++i)
        largest = std::max(largest, std::abs(start(i, j) - next(i, j)) / next(i, j));
    return largest;
  };
  report("contracting_start_largest_relative_error", largest_error(contracting));
  report("fixed_frame_start_largest_relative_error", largest_error(fixed));
  EXPECT_LT(largest_error(contracting), 1e-13);
  EXPECT_GT(largest_error(fixed), 1e-5);
  const int threads = omp_get_max_threads();
  omp_set_num_threads(threads == 1 ? 2 : 1);
  Field again(grid);
  contracting_frame_extrapolation(grid, last, earlier, 1.0 / q, again);
  omp_set_num_threads(threads);
  for (std::size_t k = 0; k < again.size(); ++k) ASSERT_EQ(again[k], contracting[k]) << k;
  const std::array<const Field*, 4> too_many{&before, &before, &before, &before};
  EXPECT_THROW(contracting_frame_extrapolation(grid, last, too_many, 1.0 / q, again),
               std::invalid_argument);
}
