// The reynolds component: the line relaxation of the transient Reynolds
// equation (the operator itself is checked through the impact runs of
// test_impact: analytic squeeze films, orders of convergence).
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "grid/Grid.hpp"
#include "reynolds/LineRelaxation.hpp"
#include "reynolds/ReynoldsOperator.hpp"
#include "rheology/Lubricant.hpp"

namespace ehlsim::reynolds {
namespace {

Field transposed(const Field& a, const Grid2D& grid) {
  Field t(grid);
  for (int j = 0; j < grid.n; ++j)
    for (int i = 0; i < grid.n; ++i) t(j, i) = a(i, j);
  return t;
}

// The gap (X^2 + Y^2)/2 + W(P) is symmetric under X <-> Y, so a sweep of Y
// lines on the transposed problem must be the transpose of a sweep of X lines:
// the same line systems, the same zebra colours, the same switch between
// Gauss-Seidel and distributive points.  An asymmetric pressure with both kinds
// of points and a cavitated rim makes every part of the sweep count.
TEST(LineRelaxation, YLinesAreXLinesOfTheTransposedProblem) {
  const Grid2D grid(33, 1.5);
  Lubricant lubricant;
  lubricant.alpha_bar = 10.0;
  OperatorSettings settings;
  settings.lambda_bar = 0.0237;  // M = 100 (model.md)
  ReynoldsOperator op(grid, lubricant, settings);
  op.set_time_step(grid.h(), 1.5);
  op.set_delta(-0.4);
  RelaxationSettings relax;
  relax.switch_ratio = 0.3;  // both kinds of points on this coarse grid
  LineRelaxation smoother(op, relax);

  std::mt19937 rng(186);
  std::uniform_real_distribution<double> noise(-0.02, 0.02);
  Field P(grid), f(grid);
  for (int j = 1; j < grid.n - 1; ++j) {
    for (int i = 1; i < grid.n - 1; ++i) {
      const double x = grid.x(i), y = grid.y(j);
      const double r2 = (x * x + y * y) / 0.64;
      P(i, j) = r2 < 1.0 ? std::sqrt(1.0 - r2) * (1.0 + 0.3 * x + 0.1 * y) + noise(rng) : 0.0;
      P(i, j) = std::max(P(i, j), 0.0);
      f(i, j) = -1.5 * (0.2 + 0.1 * x * y + noise(rng)) / grid.h();
    }
  }
  Field along_x = P;
  smoother.sweep(along_x, f, LineDirection::X);
  const SweepStats stats = smoother.last_sweep();
  EXPECT_GT(stats.gauss_seidel_points, 0);
  EXPECT_GT(stats.jacobi_points, 0);

  Field along_y = transposed(P, grid);
  smoother.sweep(along_y, transposed(f, grid), LineDirection::Y);
  EXPECT_EQ(smoother.last_sweep().jacobi_points, stats.jacobi_points);
  const Field back = transposed(along_y, grid);
  double change = 0.0;
  for (std::size_t k = 0; k < P.size(); ++k) {
    ASSERT_NEAR(back[k], along_x[k], 1e-12) << k;
    change = std::max(change, std::abs(along_x[k] - P[k]));
  }
  EXPECT_GT(change, 1e-3);  // the sweep did change the pressure
}

}  // namespace
}  // namespace ehlsim::reynolds
