// The reynolds component: the line relaxation and the local Newton step of
// the transient Reynolds equation, and the operator's derivatives they use
// (the operator itself is checked through the impact runs of test_impact:
// analytic squeeze films, orders of convergence).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <ostream>
#include <random>
#include <stdexcept>
#include <string>
#include <utility>

#include "grid/Grid.hpp"
#include "reynolds/BandSolve.hpp"
#include "reynolds/LineRelaxation.hpp"
#include "reynolds/LocalNewton.hpp"
#include "reynolds/ReynoldsOperator.hpp"
#include "rheology/Lubricant.hpp"

namespace ehlsim::reynolds {
namespace {

/// The operator of a BDF2 step on a coarse grid in contact (Delta = -0.4):
/// M = 100 (lambda_bar = 0.0237, model.md), Barus with alpha_bar = 10.
ReynoldsOperator contact_operator(const Grid2D& grid) {
  Lubricant lubricant;
  lubricant.alpha_bar = 10.0;
  OperatorSettings settings;
  settings.lambda_bar = 0.0237;
  ReynoldsOperator op(grid, lubricant, settings);
  op.set_time_step(grid.h(), 1.5);
  op.set_delta(-0.4);
  return op;
}

Field transposed(const Field& a, const Grid2D& grid) {
  Field t(grid);
  for (int j = 0; j < grid.n; ++j)
    for (int i = 0; i < grid.n; ++i) t(j, i) = a(i, j);
  return t;
}

/// A pressure in contact (radius 0.8, shaped by `shape(x, y)`, with noise and
/// a cavitated rim) and a squeeze right-hand side at the interior points of
/// `grid` (on a mirrored grid the axes included).
struct ContactData {
  Field P, f;
};
template <class Shape>
ContactData contact_data(const Grid2D& grid, unsigned seed, Shape shape) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> noise(-0.02, 0.02);
  ContactData d{Field(grid), Field(grid)};
  for (int j = grid.first_interior(); j < grid.n - 1; ++j) {
    for (int i = grid.first_interior(); i < grid.n - 1; ++i) {
      const double x = grid.x(i), y = grid.y(j);
      const double r2 = (x * x + y * y) / 0.64;
      d.P(i, j) = std::max(0.0, r2 < 1.0 ? std::sqrt(1.0 - r2) * shape(x, y) + noise(rng) : 0.0);
      d.f(i, j) = -1.5 * (0.2 + 0.1 * x * y + noise(rng)) / grid.h();
    }
  }
  return d;
}

// The gap (X^2 + Y^2)/2 + W(P) is symmetric under X <-> Y, so a sweep of Y
// lines on the transposed problem must be the transpose of a sweep of X lines:
// the same line systems, the same zebra colours, the same switch between
// Gauss-Seidel and distributive points.  An asymmetric pressure with both kinds
// of points and a cavitated rim makes every part of the sweep count.
TEST(LineRelaxation, YLinesAreXLinesOfTheTransposedProblem) {
  const Grid2D grid(33, 1.5);
  ReynoldsOperator op = contact_operator(grid);
  RelaxationSettings relax;
  relax.switch_ratio = 0.3;  // both kinds of points on this coarse grid
  LineRelaxation smoother(op, relax);

  const auto [P, f] =
      contact_data(grid, 186, [](double x, double y) { return 1.0 + 0.3 * x + 0.1 * y; });
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

// The band solver of the line systems against the product with its own
// matrix: a random diagonally dominant pentadiagonal system (the shape of the
// line systems, half-bandwidth 2) must be solved to round-off.
// A pressure even in X and Y relaxed on the full grid and on its mirrored
// quadrant: the same sweeps (lines along X and Y, both kinds of points, a
// cavitated rim), the same operator values and the same residual norm, to
// rounding.  This checks the mirror conditions of the operator, the folded
// line Jacobian on the axes, the zebra colours and the distributive changes
// across the axes.
TEST(LineRelaxation, QuadrantSweepsEqualFullGridSweeps) {
  const Grid2D full(33, 1.5);
  const Grid2D quadrant = full.quadrant();
  auto [Pq, fq] = contact_data(quadrant, 2022, [](double x, double) { return 1.0 + 0.2 * x * x; });
  Field P = unfold(Pq, quadrant);
  const Field f = unfold(fq, quadrant);
  for (int k = 0; k < full.n; ++k) P(k, 0) = P(0, k) = 0.0;  // the full grid's near edges

  ReynoldsOperator op_full = contact_operator(full);
  ReynoldsOperator op_quadrant = contact_operator(quadrant);
  RelaxationSettings relax;
  relax.switch_ratio = 30.0;  // both kinds of points on this coarse grid
  LineRelaxation smoother_full(op_full, relax);
  LineRelaxation smoother_quadrant(op_quadrant, relax);
  smoother_full.relax(P, f, 2);
  smoother_quadrant.relax(Pq, fq, 2);
  ASSERT_GT(smoother_quadrant.last_sweep().jacobi_points, 0);
  ASSERT_GT(smoother_quadrant.last_sweep().gauss_seidel_points, 0);

  const Field folded = fold(P, quadrant);
  double max_p = 0.0, max_diff = 0.0;
  for (std::size_t k = 0; k < Pq.size(); ++k) {
    max_p = std::max(max_p, std::abs(Pq[k]));
    max_diff = std::max(max_diff, std::abs(Pq[k] - folded[k]));
  }
  EXPECT_LT(max_diff, 1e-12 * max_p);
  Field N_full(full), N_quadrant(quadrant), r_full(full), r_quadrant(quadrant);
  op_full.apply(P, N_full);
  op_quadrant.apply(Pq, N_quadrant);
  for (std::size_t k = 0; k < r_full.size(); ++k) r_full[k] = f[k] - N_full[k];
  for (std::size_t k = 0; k < r_quadrant.size(); ++k) r_quadrant[k] = fq[k] - N_quadrant[k];
  // Zero on the boundary, as the FAS residual is.
  for (int k = 0; k < quadrant.n; ++k)
    r_quadrant(k, quadrant.n - 1) = r_quadrant(quadrant.n - 1, k) = 0.0;
  for (int k = 0; k < full.n; ++k)
    r_full(k, 0) = r_full(0, k) = r_full(k, full.n - 1) = r_full(full.n - 1, k) = 0.0;
  EXPECT_NEAR(op_quadrant.pressure_scaled_norm(r_quadrant), op_full.pressure_scaled_norm(r_full),
              1e-12 * op_full.pressure_scaled_norm(r_full));
  EXPECT_NEAR(op_quadrant.force(Pq), op_full.force(P), 1e-13);
}

// The switch ratio on a mesh finer than its reference grows like 1/h: a
// relaxation with ratio 15 and a reference of twice the mesh sweeps as one
// with ratio 30 does, to the bit; with a reference finer than the mesh the
// ratio is used as given.  The two ratios choose differently here, so the
// comparison can fail.
TEST(LineRelaxation, TheSwitchRatioGrowsOnMeshesFinerThanItsReference) {
  const Grid2D grid(33, 1.5);
  const auto sweep = [&](double ratio, double reference) {
    auto [P, f] = contact_data(grid, 7, [](double x, double y) { return 1.0 + 0.2 * x * y; });
    ReynoldsOperator op = contact_operator(grid);
    RelaxationSettings relax;
    relax.switch_ratio = ratio;
    relax.switch_reference_mesh = reference;
    LineRelaxation smoother(op, relax);
    smoother.relax(P, f, 2);
    return std::pair{P, smoother.last_sweep().jacobi_points};
  };
  const double h = grid.h();
  EXPECT_DOUBLE_EQ(switch_ratio_on({.switch_ratio = 3.0, .switch_reference_mesh = 4.0 * h}, h),
                   12.0);
  EXPECT_DOUBLE_EQ(switch_ratio_on({.switch_ratio = 3.0, .switch_reference_mesh = h}, h), 3.0);
  const auto [P30, jacobi30] = sweep(30.0, 0.0);
  const auto [P15, jacobi15] = sweep(15.0, 0.0);
  ASSERT_NE(jacobi30, jacobi15);
  const auto [P_raised, jacobi_raised] = sweep(15.0, 2.0 * h);
  EXPECT_EQ(jacobi_raised, jacobi30);
  EXPECT_TRUE(equal_values(P_raised, P30));
  const auto [P_fine_reference, jacobi_fine_reference] = sweep(30.0, 0.5 * h);
  EXPECT_EQ(jacobi_fine_reference, jacobi30);
  EXPECT_TRUE(equal_values(P_fine_reference, P30));
}

TEST(BandMatrix, SolvesPentadiagonalSystemsToRoundOff) {
  constexpr int kSize = 40, kHalfBand = 2;
  std::mt19937 rng(2022);
  std::uniform_real_distribution<double> entry(-1.0, 1.0);
  BandMatrix A(kSize, kHalfBand);
  for (int i = 0; i < kSize; ++i) {
    double off_diagonal = 0.0;
    for (int k = std::max(0, i - kHalfBand); k <= std::min(kSize - 1, i + kHalfBand); ++k) {
      if (k == i) continue;
      A(i, k) = entry(rng);
      off_diagonal += std::abs(A(i, k));
    }
    A(i, i) = -(off_diagonal + 0.5 + std::abs(entry(rng)));  // negative, as dN/dP
  }
  std::vector<double> x_true(kSize), rhs(kSize, 0.0);
  for (double& x : x_true) x = entry(rng);
  for (int i = 0; i < kSize; ++i)
    for (int k = std::max(0, i - kHalfBand); k <= std::min(kSize - 1, i + kHalfBand); ++k)
      rhs[i] += A(i, k) * x_true[k];
  BandMatrix work = A;
  work.solve(rhs);
  for (int i = 0; i < kSize; ++i) EXPECT_NEAR(rhs[i], x_true[i], 1e-13) << i;
}

// Where the pressure is zero and the equation asks for none (the residual
// would lower it), a sweep must leave it at exactly zero; lines made only of
// such points are not solved at all, and the points next to the pressurized
// region are where that shortcut must not reach.
TEST(LineRelaxation, LeavesTheCavitatedRegionAtZero) {
  const Grid2D grid(33, 1.5);
  ReynoldsOperator op = contact_operator(grid);
  LineRelaxation smoother(op, RelaxationSettings{});
  // A Hertz-like pressure on R < 0.6; the right-hand side of an opening gap
  // (f > N(0) away from the contact: the equation asks for negative pressure).
  Field P(grid), f(grid);
  for (int j = 1; j < grid.n - 1; ++j) {
    for (int i = 1; i < grid.n - 1; ++i) {
      const double r2 = (grid.x(i) * grid.x(i) + grid.y(j) * grid.y(j)) / 0.36;
      P(i, j) = r2 < 1.0 ? std::sqrt(1.0 - r2) : 0.0;
    }
  }
  op.update_coefficients(Field(grid));
  for (int j = 1; j < grid.n - 1; ++j)
    for (int i = 1; i < grid.n - 1; ++i) f(i, j) = op.apply_at(Field(grid), i, j) + 1.0;
  Field relaxed = P;
  smoother.relax(relaxed, f, 2);
  double inside_change = 0.0;
  for (int j = 1; j < grid.n - 1; ++j) {
    for (int i = 1; i < grid.n - 1; ++i) {
      const double r = std::hypot(grid.x(i), grid.y(j));
      if (r > 0.6 + 3.0 * grid.h()) {
        ASSERT_EQ(relaxed(i, j), 0.0) << i << ", " << j;
      }
      if (r < 0.5) inside_change = std::max(inside_change, std::abs(relaxed(i, j) - P(i, j)));
    }
  }
  EXPECT_GT(inside_change, 1e-3);  // the pressurized region was relaxed
}

// Where a point's pressure and its four neighbours' are zero, apply_at takes
// the transport term alone, without the faces (the cavitated region, most of
// the domain in the rebound): it must be the full stencil's value, for the
// squeeze term of the impact and the upwind wedge of the rolling contact, with
// every face mean.
// With surface.waviness_wavelength = 1e-308 and no amplitude the wave number
// overflowed and 0 cos(inf) made the gap NaN: the run failed at T = 0 with a
// residual that was not finite.  No amplitude, no wave, whatever its length.
TEST(Waviness, WithoutAnAmplitudeThereIsNoWaveWhateverItsLength) {
  for (const double wavelength : {1e-308, 1.0, 1e308})
    EXPECT_EQ((Waviness{0.0, wavelength, 30.0}.height(0.3, -0.7)), 0.0) << wavelength;
  // A wave along X: crests at X = 0 and X = 0.5, a trough at X = 0.25.
  const Waviness along_x{0.1, 0.5, 0.0};
  EXPECT_DOUBLE_EQ(along_x.height(0.5, 0.9), 0.1);
  EXPECT_DOUBLE_EQ(along_x.height(0.25, -0.4), -0.1);
}

TEST(ReynoldsOperator, ACavitatedNeighbourhoodGivesTheFullStencilsValue) {
  const Grid2D grid(33, 1.5);
  const ContactData d = contact_data(grid, 5, [](double, double) { return 1.0; });
  for (const double wedge : {0.0, 1.0}) {
    for (const FaceMean mean : {FaceMean::Arithmetic, FaceMean::Harmonic, FaceMean::Logarithmic}) {
      Lubricant lubricant;
      lubricant.alpha_bar = 10.0;
      OperatorSettings settings;
      settings.lambda_bar = 0.0237;
      settings.wedge = wedge;
      settings.face_mean = mean;
      ReynoldsOperator op(grid, lubricant, settings);
      op.set_time_step(grid.h(), 1.5);
      op.set_delta(-0.4);
      op.update_coefficients(d.P);
      int cavitated = 0;
      for (int j = 1; j < grid.n - 1; ++j) {
        for (int i = 1; i < grid.n - 1; ++i) {
          if (!is_cavitated_around(d.P, i, j)) continue;
          ++cavitated;
          ASSERT_EQ(op.apply_at(d.P, i, j), op.apply_at(d.P, i, j, op.faces_at(i, j)))
              << i << ", " << j << ", wedge " << wedge;
        }
      }
      EXPECT_GT(cavitated, grid.n * grid.n / 2);
    }
  }
}

// The local Newton step differentiates the stencil with xi's own dependence on
// the pressure (rheology and film).  With the exact derivative, one step from
// P* + eps B leaves a residual O(eps^2): ten times less eps, a hundred times
// less residual.  A derivative with xi frozen (a Picard step) or a wrong term
// converges linearly, with the same ratio for every eps.
struct NewtonCase {
  bool mirrored;
  FaceMean mean;
  bool roelands_dh;  ///< Roelands viscosity and Dowson-Higginson density, else Barus
};

std::string case_name(const NewtonCase& c) {
  const char* mean = c.mean == FaceMean::Arithmetic ? "Arithmetic"
                     : c.mean == FaceMean::Harmonic ? "Harmonic"
                                                    : "Logarithmic";
  return std::string(c.mirrored ? "Quadrant" : "Full") + mean +
         (c.roelands_dh ? "RoelandsDowsonHigginson" : "Barus");
}
void PrintTo(const NewtonCase& c, std::ostream* os) { *os << case_name(c); }

class LocalNewtonOrder : public ::testing::TestWithParam<NewtonCase> {};

/// max |f - N(P)| over the interior (the coefficients brought up to date).
double max_residual(ReynoldsOperator& op, const Field& P, const Field& f) {
  Field N(op.grid());
  op.apply(P, N);
  const Grid2D& g = op.grid();
  double worst = 0.0;
  for (int j = g.first_interior(); j < g.n - 1; ++j)
    for (int i = g.first_interior(); i < g.n - 1; ++i)
      worst = std::max(worst, std::abs(f(i, j) - N(i, j)));
  return worst;
}

TEST_P(LocalNewtonOrder, OneStepSquaresTheError) {
  const NewtonCase c = GetParam();
  // 33^2 points on [-1.5, 1.5]^2, or its quadrant: 961 or 256 unknowns.
  const Grid2D grid = c.mirrored ? Grid2D(33, 1.5).quadrant() : Grid2D(17, 1.5);
  Lubricant lubricant;
  if (c.roelands_dh) {
    lubricant.viscosity = ViscosityModel::Roelands;
    lubricant.density = DensityModel::DowsonHigginson;
    lubricant.eta0_Pa_s = 0.04;
    lubricant.roelands_z = 0.6;
    lubricant.ph_star_Pa = 1e9;
  } else {
    lubricant.alpha_bar = 10.0;
  }
  OperatorSettings settings;
  settings.lambda_bar = 0.0237;
  settings.face_mean = c.mean;
  ReynoldsOperator op(grid, lubricant, settings);
  op.set_time_step(grid.h(), 1.5);
  op.set_delta(0.05);  // an open film: H > 0 everywhere, no kink of max(H, 0)
  // A smooth pressure positive at every unknown (no point held), and a bump.
  Field exact(grid), bump(grid);
  for (int j = grid.first_interior(); j < grid.n - 1; ++j) {
    for (int i = grid.first_interior(); i < grid.n - 1; ++i) {
      const double x = grid.x(i), y = grid.y(j);
      exact(i, j) = 0.02 + 0.6 * std::exp(-(x * x + y * y) / 0.5);
      bump(i, j) = std::exp(-((x - 0.3) * (x - 0.3) + y * y) / 0.2);
    }
  }
  Field f(grid);
  op.apply(exact, f);
  const int first = grid.first_interior();
  const Window whole{first, grid.n - 2, first, grid.n - 2};
  double ratio[2];
  for (int k = 0; k < 2; ++k) {
    const double eps = k == 0 ? 1e-2 : 1e-3;
    Field P = exact;
    for (std::size_t q = 0; q < P.size(); ++q) P[q] += eps * bump[q];
    const double before = max_residual(op, P, f);
    const LocalNewtonStep step = local_newton_step(op, P, f, {whole});
    EXPECT_EQ(step.windows, 1);
    EXPECT_EQ(step.unknowns, whole.size());
    EXPECT_EQ(step.held, 0);
    EXPECT_EQ(step.undone, 0);
    ratio[k] = max_residual(op, P, f) / before;
  }
  EXPECT_LT(ratio[0], 0.05);
  EXPECT_LT(ratio[1], 0.2 * ratio[0]) << "linear, not quadratic: a derivative term is missing";
}

INSTANTIATE_TEST_SUITE_P(Grids, LocalNewtonOrder,
                         ::testing::Values(NewtonCase{false, FaceMean::Arithmetic, false},
                                           NewtonCase{true, FaceMean::Arithmetic, false},
                                           NewtonCase{true, FaceMean::Harmonic, false},
                                           NewtonCase{true, FaceMean::Logarithmic, false},
                                           NewtonCase{false, FaceMean::Arithmetic, true},
                                           NewtonCase{true, FaceMean::Logarithmic, true}),
                         [](const ::testing::TestParamInfo<NewtonCase>& param_info) {
                           return case_name(param_info.param);
                         });

namespace {
/// A Hertz-like pressure on R < 0.6 and the right-hand side it solves.
struct HertzLike {
  Field exact, f;
  HertzLike(const Grid2D& grid, ReynoldsOperator& op) : exact(grid), f(grid) {
    for (int j = 1; j < grid.n - 1; ++j) {
      for (int i = 1; i < grid.n - 1; ++i) {
        const double r2 = (grid.x(i) * grid.x(i) + grid.y(j) * grid.y(j)) / 0.36;
        exact(i, j) = r2 < 1.0 ? std::sqrt(1.0 - r2) : 0.0;
      }
    }
    op.apply(exact, f);
  }
};

bool in_any(const std::vector<Window>& windows, int i, int j) {
  return std::any_of(windows.begin(), windows.end(),
                     [&](const Window& w) { return w.contains(i, j); });
}

/// The largest |P - exact| over the grid; fails at a point outside
/// `windows` that changed, or a cavitated point that took pressure.
double error_after_step(const Field& P, const Field& exact, const std::vector<Window>& windows) {
  double error = 0.0;
  for (int j = 0; j < exact.n(); ++j) {
    for (int i = 0; i < exact.n(); ++i) {
      if (!in_any(windows, i, j)) {
        EXPECT_EQ(P(i, j), exact(i, j)) << i << ", " << j;
      }
      // The cavitated region, to rounding where the residual of the perturbed
      // state asks for pressure, and Newton finds none.
      if (exact(i, j) == 0.0) {
        EXPECT_LT(P(i, j), 1e-12) << i << ", " << j;
      }
      error = std::max(error, std::abs(P(i, j) - exact(i, j)));
    }
  }
  return error;
}
}  // namespace

// The window is where the residual is largest, and a step changes nothing
// outside it; the cavitated region stays at 0.
TEST(LocalNewton, RepairsALocalErrorInsideItsWindowOnly) {
  const Grid2D grid(33, 1.5);
  ReynoldsOperator op = contact_operator(grid);
  const HertzLike hertz(grid, op);
  const int ic = 18, jc = 14;
  Field P = hertz.exact;
  P(ic, jc) += 0.2;
  const std::vector<Window> windows = windows_at_largest_residuals(op, P, hertz.f, 3, 1);
  ASSERT_EQ(windows.size(), 1u);
  ASSERT_TRUE(windows[0].contains(ic, jc));
  EXPECT_EQ(windows[0].size(), 49);
  const LocalNewtonStep step = local_newton_step(op, P, hertz.f, windows);
  EXPECT_EQ(step.unknowns, 49);
  EXPECT_EQ(step.undone, 0);
  EXPECT_LT(error_after_step(P, hertz.exact, windows), 0.2 * 1e-2);
}

// A window whose Jacobian is singular gets no step: P stays as it was and the
// caller gets the residual it passed, to record its cycle and judge it (a
// rolling run whose iterate had blown up lost such a cycle from its history,
// and numbered the next one after it).  Here rigid bodies that overlap
// (H < 0 over the contact: no flow, and no elastic term) make every row of
// the window zero.
TEST(LocalNewton, ASingularWindowGetsNoStep) {
  const Grid2D grid(33, 1.5);
  Lubricant lubricant;
  lubricant.alpha_bar = 10.0;
  OperatorSettings settings;
  settings.elastic = false;
  ReynoldsOperator op(grid, lubricant, settings);
  op.set_time_step(grid.h(), 1.5);
  op.set_delta(-2.0);
  const HertzLike hertz(grid, op);
  Field P = hertz.exact;
  Field f = hertz.f;
  f(16, 16) += 1.0;
  const Field before = P;
  const std::vector<Window> windows = windows_at_largest_residuals(op, P, f, 2, 1);
  ASSERT_TRUE(windows.size() == 1 && windows[0].contains(16, 16));
  EXPECT_THROW(local_newton_step(op, P, f, windows), std::runtime_error);
  int settled = 0;
  const GlobalUnknown unchanged{[&] {
                                  ++settled;
                                  return 0.0;
                                },
                                [](double) {}};
  const double residual = 0.5;
  EXPECT_EQ(newton_on_worst_windows(op, P, f, {2, 1}, residual, unchanged), residual);
  EXPECT_EQ(settled, 0);
  for (int j = 0; j < grid.n; ++j)
    for (int i = 0; i < grid.n; ++i) ASSERT_EQ(P(i, j), before(i, j)) << i << ", " << j;
}

// Errors far apart each get a window, largest first; two errors closer than a
// window share one (no two windows overlap), and one step repairs all of them.
TEST(LocalNewton, SolvesOneWindowPerSeparateError) {
  const Grid2D grid(65, 1.5);
  ReynoldsOperator op = contact_operator(grid);
  const HertzLike hertz(grid, op);
  Field P = hertz.exact;
  // In the contact (R < 0.6: within 12 meshes of (32, 32)).
  P(26, 26) += 0.2;  // the largest
  P(40, 28) += 0.15;
  P(30, 40) += 0.1;
  P(33, 40) += 0.1;  // 3 meshes from the one before: inside its window
  const int half_width = 3;
  const std::vector<Window> windows = windows_at_largest_residuals(op, P, hertz.f, half_width, 3);
  ASSERT_EQ(windows.size(), 3u);
  EXPECT_TRUE(windows[0].contains(26, 26));
  EXPECT_TRUE(windows[1].contains(40, 28));
  EXPECT_TRUE(windows[2].contains(30, 40) && windows[2].contains(33, 40));
  // With more allowed, more windows where the films the errors change leave
  // residuals (the elastic squeeze in the contact), none overlapping.
  const std::vector<Window> many = windows_at_largest_residuals(op, P, hertz.f, half_width, 100);
  EXPECT_GT(many.size(), 3u);
  for (std::size_t a = 0; a < many.size(); ++a) {
    for (std::size_t b = a + 1; b < many.size(); ++b) {
      const Window& u = many[a];
      const Window& v = many[b];
      EXPECT_TRUE(u.i1 < v.i0 || v.i1 < u.i0 || u.j1 < v.j0 || v.j1 < u.j0) << a << ", " << b;
    }
  }
  const LocalNewtonStep step = local_newton_step(op, P, hertz.f, windows);
  EXPECT_EQ(step.windows, 3);
  EXPECT_EQ(step.unknowns, 3 * 49);
  EXPECT_EQ(step.undone, 0);
  // Each window is solved with the others' errors still in the film, so what
  // is left is their coupling through the elastic kernel, a few per cent of
  // the largest error (measured: 0.0049).
  EXPECT_LT(error_after_step(P, hertz.exact, windows), 0.05 * 0.2);
}

// The exact slopes of the three face means against central differences,
// near equal values (the log mean's series branch) and far apart.
TEST(FaceCoefficientSlopes, MatchTheDifferencesOfTheMean) {
  for (const FaceMean mean : {FaceMean::Arithmetic, FaceMean::Harmonic, FaceMean::Logarithmic}) {
    for (const auto& [a, b] : {std::pair{1.0, 1.0 + 1e-6}, std::pair{2.0, 3.0},
                               std::pair{1e-8, 5.0}, std::pair{7.0, 0.01}}) {
      const FaceSlopes slope = face_coefficient_slopes(a, b, mean);
      const double da = 1e-6 * a, db = 1e-6 * b;
      const double fa =
          (face_coefficient(a + da, b, mean) - face_coefficient(a - da, b, mean)) / (2.0 * da);
      const double fb =
          (face_coefficient(a, b + db, mean) - face_coefficient(a, b - db, mean)) / (2.0 * db);
      // Truncation error, plus the rounding of the mean divided by the step.
      const double mean_rounding = 1e-15 * face_coefficient(a, b, mean);
      EXPECT_NEAR(slope.a, fa, 1e-5 * std::max(1.0, std::abs(fa)) + mean_rounding / da)
          << a << ", " << b;
      EXPECT_NEAR(slope.b, fb, 1e-5 * std::max(1.0, std::abs(fb)) + mean_rounding / db)
          << a << ", " << b;
    }
  }
}

// d ln(rho / eta) / dP: -alpha_bar for Barus and an incompressible fluid.
TEST(FlowFactorLogSlope, IsMinusAlphaForBarus) {
  Lubricant lubricant;
  lubricant.alpha_bar = 16.9;
  const ReynoldsOperator op(Grid2D(17, 1.5), lubricant, OperatorSettings{});
  for (const double p : {0.0, 0.5, 3.0, 60.0})  // 60: eta_bar itself overflows
    EXPECT_NEAR(op.flow_factor_log_slope(p), -16.9, 1e-6) << p;
  EXPECT_EQ(op.flow_factor_log_slope(-0.1), 0.0);
}

}  // namespace
}  // namespace ehlsim::reynolds
