// The generic multigrid pieces on their own: transfers and the FAS solver on a
// model nonlinear problem with a known solution.
#include <gtest/gtest.h>
#include <omp.h>

#include <cmath>
#include <numbers>
#include <vector>

#include "multigrid/Fas.hpp"
#include "multigrid/Transfer.hpp"

namespace ehlsim::multigrid {
namespace {

template <class F>
Field sample(const Grid2D& g, F fn) {
  Field u(g);
  for (int j = 0; j < g.n; ++j)
    for (int i = 0; i < g.n; ++i) u(i, j) = fn(g.x(i), g.y(j));
  return u;
}

TEST(Transfer, BilinearIsExactForBilinearFunctions) {
  const Grid2D fine(17, 1.0);
  const auto fn = [](double x, double y) { return 1.0 + 2.0 * x - 3.0 * y + 0.5 * x * y; };
  const Field coarse = sample(fine.coarser(), fn);
  Field u(fine);
  prolong_bilinear_add(coarse, u);
  const Field exact = sample(fine, fn);
  for (std::size_t k = 0; k < u.size(); ++k) EXPECT_NEAR(u[k], exact[k], 1e-14);
}

TEST(Transfer, CubicIsExactForCubicPolynomials) {
  const Grid2D fine(33, 1.5);
  const auto fn = [](double x, double y) { return x * x * x - 2.0 * x * y * y + y * y - 0.3; };
  Field u(fine);
  prolong_cubic(sample(fine.coarser(), fn), u);
  const Field exact = sample(fine, fn);
  // Interior points use the 4-point cubic rule (exact for cubics); the intervals
  // next to the boundary use a quadratic rule, exact only up to degree 2.
  for (int j = 3; j < fine.n - 3; ++j)
    for (int i = 3; i < fine.n - 3; ++i) EXPECT_NEAR(u(i, j), exact(i, j), 1e-12);
}

TEST(Transfer, FullWeightingPreservesSmoothFieldsToSecondOrder) {
  const Grid2D fine(65, 1.0);
  const auto fn = [](double x, double y) { return std::sin(x) * std::cos(y); };
  Field coarse(fine.coarser());
  restrict_full_weighting(sample(fine, fn), coarse);
  const Grid2D cg = fine.coarser();
  const double h = fine.h();
  for (int J = 1; J < cg.n - 1; ++J)
    for (int I = 1; I < cg.n - 1; ++I)
      // Full weighting of a smooth function equals it up to (h^2 / 4) Laplacian.
      EXPECT_NEAR(coarse(I, J), fn(cg.x(I), cg.y(J)), 0.6 * h * h);
}

// The transfers and the element-wise field loops run on the threads on grids
// of 64^2 points and more; each element is written by one thread, so 1, 2 and
// 3 threads must give the same bits (docs/usage.md, "Reproducibility").
TEST(Transfer, ThreadedTransfersGiveTheBitsOfOneThread) {
  for (const bool mirrored : {false, true}) {
    const Grid2D fine(257, 1.0, mirrored);
    ASSERT_TRUE(worth_threads(fine.coarser()));
    const auto fn = [](double x, double y) { return std::exp(-3.0 * x * x) * std::cos(5.0 * y); };
    const Field u = sample(fine, fn);
    const int threads_before = omp_get_max_threads();
    std::vector<Field> results;
    for (const int threads : {1, 2, 3}) {
      omp_set_num_threads(threads);
      Field injected(fine.coarser()), restricted(fine.coarser()), prolonged(fine);
      inject(u, injected);
      restrict_full_weighting(u, restricted);
      copy_into(u, prolonged);
      prolong_bilinear_add(restricted, prolonged);
      Field change(fine);
      difference(prolonged, u, change);
      add_to(change, change);
      for (const Field* f : {&injected, &restricted, &prolonged, &change}) results.push_back(*f);
    }
    omp_set_num_threads(threads_before);
    for (std::size_t r = 4; r < results.size(); ++r)
      EXPECT_TRUE(equal_values(results[r], results[r % 4]))
          << "result " << r << ", mirrored " << mirrored;
    // equal_values sees a single differing element, wherever it is.
    Field other = results[2];
    other[other.size() - 1] += 1.0;
    EXPECT_FALSE(equal_values(other, results[2]));
  }
}

/// Model problem: -Laplace(u) + u^3 = f on [-1, 1]^2, u = 0 on the boundary,
/// with pointwise nonlinear Gauss-Seidel (red-black) as the smoother.
class ModelLevel final : public FasLevel {
 public:
  explicit ModelLevel(const Grid2D& g) : grid_(g) {}
  /// A level whose smoother leaves a large error at the centre after every
  /// relaxation: a coarse problem that cannot represent the solution.
  void sabotage(double amount) { sabotage_ = amount; }
  [[nodiscard]] const Grid2D& grid() const override { return grid_; }
  void apply(const Field& u, Field& Nu) override {
    Nu.fill(0.0);
    for (int j = 1; j < grid_.n - 1; ++j)
      for (int i = 1; i < grid_.n - 1; ++i) Nu(i, j) = at(u, i, j);
  }
  void residual(const Field& u, const Field& f, Field& r) override {
    apply(u, r);
    for (std::size_t k = 0; k < r.size(); ++k) r[k] = f[k] - r[k];
    for (int k = 0; k < grid_.n; ++k) r(k, 0) = r(k, grid_.n - 1) = r(0, k) = r(grid_.n - 1, k) = 0;
  }
  void relax(Field& u, const Field& f, int sweeps) override {
    const double h2 = grid_.h() * grid_.h();
    for (int s = 0; s < sweeps; ++s)
      for (int colour = 0; colour < 2; ++colour)
        for (int j = 1; j < grid_.n - 1; ++j)
          for (int i = 1 + (j + colour) % 2; i < grid_.n - 1; i += 2) {
            const double diag = 4.0 / h2 + 3.0 * u(i, j) * u(i, j);
            u(i, j) += (f(i, j) - at(u, i, j)) / diag;
          }
    u((grid_.n - 1) / 2, (grid_.n - 1) / 2) += sabotage_;
  }
  void project(Field& /*u*/) override {}

 private:
  double at(const Field& u, int i, int j) const {
    const double h2 = grid_.h() * grid_.h();
    return (4.0 * u(i, j) - u(i - 1, j) - u(i + 1, j) - u(i, j - 1) - u(i, j + 1)) / h2 +
           u(i, j) * u(i, j) * u(i, j);
  }
  Grid2D grid_;
  double sabotage_ = 0.0;
};

/// The hierarchy 129^2 ... 5^2 of the model problem, with the solver's right-hand
/// side for the solution sin(pi x) sin(pi y).
struct ModelHierarchy {
  std::vector<std::unique_ptr<ModelLevel>> owned;
  std::vector<FasLevel*> levels;
  explicit ModelHierarchy(int n) {
    for (Grid2D g(n, 1.0); g.n >= 5; g = g.coarser()) {
      owned.push_back(std::make_unique<ModelLevel>(g));
      levels.push_back(owned.back().get());
      if (!g.coarser().coarsenable()) break;
    }
  }
  void set_rhs(FasSolver& solver) const {
    const Grid2D& g = levels.front()->grid();
    const double pi = std::numbers::pi;
    Field& f = solver.rhs();
    for (int j = 1; j < g.n - 1; ++j)
      for (int i = 1; i < g.n - 1; ++i) {
        const double u = std::sin(pi * g.x(i)) * std::sin(pi * g.y(j));
        f(i, j) = 2.0 * pi * pi * u + u * u * u;
      }
  }
};

TEST(FasSolver, SafeguardUndoesCorrectionsThatMakeTheResidualWorse) {
  // The second level's smoother plants an error of 1000 at the centre: its
  // correction would raise the fine residual by orders of magnitude.  Guarded,
  // the correction is undone, and the cycle is exactly its fine-grid smoothing.
  const FasSettings defaults;
  const auto one_cycle = [&](double safeguard, long* rejected, Field* u) {
    ModelHierarchy model(65);
    model.owned[1]->sabotage(1000.0);
    FasSettings settings;
    settings.correction_safeguard = safeguard;
    FasSolver solver(model.levels, settings);
    model.set_rhs(solver);
    const double before = solver.residual_norm();
    solver.cycle();
    *rejected = solver.rejected_corrections();
    *u = solver.solution();
    return solver.residual_norm() / before;
  };
  long rejected = 0;
  Field unguarded, guarded;
  EXPECT_GT(one_cycle(0.0, &rejected, &unguarded), 100.0);
  EXPECT_EQ(rejected, 0);
  const double guarded_ratio = one_cycle(10.0, &rejected, &guarded);
  EXPECT_LT(guarded_ratio, 2.0);
  // Only the finest level's correction is undone: the second level judges its
  // own correction against a residual that already holds the planted error.
  EXPECT_EQ(rejected, 1);

  ModelHierarchy model(65);
  FasSolver reference(model.levels, defaults);
  model.set_rhs(reference);
  Field smoothed(model.levels.front()->grid());
  model.levels.front()->relax(smoothed, reference.rhs(),
                              defaults.pre_sweeps + defaults.post_sweeps);
  for (std::size_t k = 0; k < smoothed.size(); ++k) ASSERT_EQ(guarded[k], smoothed[k]) << k;
}

TEST(FasSolver, SafeguardLeavesAWorkingCycleAlone) {
  ModelHierarchy model(129);
  FasSettings settings;
  settings.correction_safeguard = 10.0;
  FasSolver solver(model.levels, settings);
  model.set_rhs(solver);
  const double start = solver.residual_norm();
  for (int c = 0; c < 6; ++c) solver.cycle();
  EXPECT_EQ(solver.rejected_corrections(), 0);
  EXPECT_LT(solver.residual_norm() / start, std::pow(0.15, 6));
}

TEST(FasSolver, VCycleReducesTheResidualOfANonlinearProblemByTenPerCycle) {
  std::vector<std::unique_ptr<ModelLevel>> owned;
  std::vector<FasLevel*> levels;
  for (Grid2D g(129, 1.0); g.n >= 5; g = g.coarser()) {
    owned.push_back(std::make_unique<ModelLevel>(g));
    levels.push_back(owned.back().get());
    if (!g.coarser().coarsenable()) break;
  }
  FasSolver solver(levels, FasSettings{});
  const Grid2D& g = levels.front()->grid();
  const double pi = std::numbers::pi;
  const auto exact = [&](double x, double y) { return std::sin(pi * x) * std::sin(pi * y); };
  Field& f = solver.rhs();
  for (int j = 1; j < g.n - 1; ++j)
    for (int i = 1; i < g.n - 1; ++i) {
      const double u = exact(g.x(i), g.y(j));
      f(i, j) = 2.0 * pi * pi * u + u * u * u;
    }
  double previous = solver.residual_norm();
  for (int c = 0; c < 6; ++c) {
    solver.cycle();
    const double now = solver.residual_norm();
    // V(2,1) with Gauss-Seidel reaches about 0.1 per cycle on Poisson-like problems.
    EXPECT_LT(now / previous, 0.15) << "cycle " << c;
    previous = now;
  }
  double error = 0.0;
  for (int j = 0; j < g.n; ++j)
    for (int i = 0; i < g.n; ++i)
      error = std::max(error, std::abs(solver.solution()(i, j) - exact(g.x(i), g.y(j))));
  EXPECT_LT(error, 1e-3);  // discretization error ~ (pi h)^2 / 12
}

}  // namespace
}  // namespace ehlsim::multigrid
