// Elastic half-space deformation: cell kernel, direct and FFT evaluation,
// analytic solutions (model.md, "Analytic checks").
#include <gtest/gtest.h>
#include <omp.h>

#include <cmath>
#include <numbers>
#include <random>
#include <vector>

#include "elastic/CellKernel.hpp"
#include "elastic/Deformation.hpp"

using namespace ehlsim;

namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kTwoOverPi2 = 2.0 / (kPi * kPi);  // prefactor of the operator (model.md)
constexpr double kHalfWidth = 1.5;                 // default domain of model.md

Field sample(const Grid2D& g, double (*f)(double r)) {
  Field P(g);
  for (int j = 0; j < g.n; ++j)
    for (int i = 0; i < g.n; ++i) P(i, j) = f(std::hypot(g.x(i), g.y(j)));
  return P;
}

// Hertz pressure of unit contact radius and its deformation (model.md).
double hertz_pressure(double r) { return r < 1.0 ? std::sqrt(1.0 - r * r) : 0.0; }
double hertz_deformation(double r) {
  if (r <= 1.0) return 1.0 - 0.5 * r * r;
  return ((2.0 - r * r) * std::asin(1.0 / r) + std::sqrt(r * r - 1.0)) / kPi;
}

// P = (1 - r^2)^(3/2): smoother at the edge than Hertz (P'' ~ (1-r)^(-1/2)
// instead of P' ~ (1-r)^(-1/2)).  Since (1 - r^2)^(3/2) = Int_0^1 3a sqrt(a^2 - r^2)_+ da,
// W is the superposition of Hertz deformations a^2 W_H(r/a):
//   r <= 1: W = (3/4)(1 - r^2) + (9/32) r^4   (Johnson's 8 - 8r^2 + 3r^4 form),
//   r > 1:  W = (3 r^4/pi) I(t), t = asin(1/r),
//           I(t) = -t sin^2 t cos^2 t / 2 + (3/2)(t/8 - sin(4t)/32).
double smooth_pressure(double r) { return r < 1.0 ? std::pow(1.0 - r * r, 1.5) : 0.0; }
double smooth_deformation(double r) {
  const double r4 = r * r * r * r;
  if (r <= 1.0) return 0.75 * (1.0 - r * r) + 9.0 / 32.0 * r4;
  const double t = std::asin(1.0 / r), s = std::sin(t), c = std::cos(t);
  const double I = -0.5 * t * s * s * c * c + 1.5 * (t / 8.0 - std::sin(4.0 * t) / 32.0);
  return 3.0 * r4 / kPi * I;
}

double max_abs(const Field& f) {
  double m = 0.0;
  for (std::size_t k = 0; k < f.size(); ++k) m = std::max(m, std::fabs(f[k]));
  return m;
}

double max_diff(const Field& a, const Field& b) {
  double m = 0.0;
  for (std::size_t k = 0; k < a.size(); ++k) m = std::max(m, std::fabs(a[k] - b[k]));
  return m;
}

}  // namespace

// ---------------------------------------------------------------- cell kernel

TEST(CellKernel, Symmetries) {
  const double h = 0.1;
  for (const auto& [x, y] : std::vector<std::pair<double, double>>{
           {0.0, 0.0}, {0.1, 0.0}, {0.3, 0.2}, {1.7, 0.4}, {0.05, 0.35}}) {
    const double k = cell_kernel(x, y, h);
    EXPECT_GT(k, 0.0);
    // Even in x and y, symmetric in (x, y): exact up to the rounding of a
    // four-term sum of O(r log r) terms.
    EXPECT_NEAR(cell_kernel(-x, y, h), k, 1e-15);
    EXPECT_NEAR(cell_kernel(x, -y, h), k, 1e-15);
    EXPECT_NEAR(cell_kernel(y, x, h), k, 1e-15);
  }
}

TEST(CellKernel, SelfInfluenceClosedForm) {
  // Int Int over the unit square of 1/r from its centre = 4 ln(1 + sqrt 2).
  const double h = 0.02;
  EXPECT_NEAR(cell_kernel(0.0, 0.0, h) / (kTwoOverPi2 * 4.0 * h * std::asinh(1.0)), 1.0, 1e-14);
}

TEST(CellKernel, MatchesQuadratureOfOneOverR) {
  // 20-point Gauss-Legendre per direction of (2/pi^2)/|r - r'| over a cell
  // that does not contain the point: the integrand is analytic there, so the
  // quadrature is accurate to well below 1e-10 at distance >= 1.5 cells.
  const std::vector<double> xg = {0.0765265211334973, 0.2277858511416451, 0.3737060887154195,
                                  0.5108670019508271, 0.6360536807265150, 0.7463319064601508,
                                  0.8391169718222188, 0.9122344282513259, 0.9639719272779138,
                                  0.9931285991850949};
  const std::vector<double> wg = {0.1527533871307258, 0.1491729864726037, 0.1420961093183820,
                                  0.1316886384491766, 0.1181945319615184, 0.1019301198172404,
                                  0.0832767415767048, 0.0626720483341091, 0.0406014298003869,
                                  0.0176140071391521};
  const double h = 0.5;
  for (const auto& [x, y] :
       std::vector<std::pair<double, double>>{{1.0, 0.0}, {1.0, 0.5}, {0.75, 1.5}, {2.0, 2.0}}) {
    double sum = 0.0;
    for (std::size_t a = 0; a < 2 * xg.size(); ++a) {
      const double u = (a < xg.size() ? xg[a] : -xg[a - xg.size()]) * 0.5 * h;
      const double wu = wg[a % xg.size()] * 0.5 * h;
      for (std::size_t b = 0; b < 2 * xg.size(); ++b) {
        const double v = (b < xg.size() ? xg[b] : -xg[b - xg.size()]) * 0.5 * h;
        const double wv = wg[b % xg.size()] * 0.5 * h;
        sum += wu * wv / std::hypot(x - u, y - v);
      }
    }
    EXPECT_NEAR(cell_kernel(x, y, h) / (kTwoOverPi2 * sum), 1.0, 1e-10) << x << ", " << y;
  }
}

namespace {

// Averaging f = 1/r over a square of side h (Taylor expansion of the
// integrand, moments h^2/12, h^4/80):
//   K / ((2/pi^2) h^2) = f + (h^2/24)(f_xx + f_yy) + (h^4/1920)(f_xxxx + f_yyyy)
//                        + (h^4/576) f_xxyy + O(h^6/r^7),
// with f_xx + f_yy = 1/r^3 (f is harmonic in 3-D), f_xxxx = 105x^4/r^9 -
// 90x^2/r^7 + 9/r^5 and f_xxyy = 105x^2y^2/r^9 - 15/r^5 + 3/r^5.
double far_field_kernel(double x, double y, double h) {
  const double r2 = x * x + y * y, r = std::sqrt(r2);
  const double r5 = r2 * r2 * r, r7 = r5 * r2, r9 = r7 * r2;
  const double x2 = x * x, y2 = y * y;
  const double fxxxx = 105.0 * x2 * x2 / r9 - 90.0 * x2 / r7 + 9.0 / r5;
  const double fyyyy = 105.0 * y2 * y2 / r9 - 90.0 * y2 / r7 + 9.0 / r5;
  const double fxxyy = 105.0 * x2 * y2 / r9 - 12.0 / r5;
  const double h2 = h * h, h4 = h2 * h2;
  return kTwoOverPi2 * h2 *
         (1.0 / r + h2 / (24.0 * r2 * r) + h4 / 1920.0 * (fxxxx + fyyyy) + h4 / 576.0 * fxxyy);
}

}  // namespace

TEST(CellKernel, FarFieldExpansion) {
  // On the table of a 1025^2 grid.  The O((h/r)^6) remainder of the
  // expansion is 6.5e-12 relative at 20 cells (measured), < 1e-18 beyond 500
  // cells; there the test sees the table's own rounding.  The table is built
  // in long double: a plain double closed form is off by up to 1.4e-9 on far
  // off-diagonal entries (e.g. offset (1005, 686)) and would fail the 1e-11.
  const Grid2D g(1025, kHalfWidth);
  const KernelTable K(g);
  const double h = g.h();
  struct Offset {
    int a, b;
  };
  for (const auto [a, b] : std::vector<Offset>{{20, 0},
                                               {0, -20},
                                               {20, 20},
                                               {100, 0},
                                               {37, 85},
                                               {500, 500},
                                               {1005, 686},
                                               {-686, 1005},
                                               {1024, 0},
                                               {1024, 1024},
                                               {700, -1024}}) {
    const double tol = std::hypot(a, b) < 500.0 ? 1e-10 : 1e-11;
    EXPECT_NEAR(K(a, b) / far_field_kernel(a * h, b * h, h), 1.0, tol) << a << ", " << b;
  }
  // The leading term alone, (2/pi^2) h^2 / r, is off by (h/r)^2/24 (to 1%).
  for (const int a : {20, 100, 500}) {
    const double q = 1.0 / a;  // h / r
    EXPECT_NEAR((K(a, 0) / (kTwoOverPi2 * h * q) - 1.0) / (q * q / 24.0), 1.0, 1e-2);
  }
}

TEST(CellKernel, TableMatchesClosedFormNearby) {
  const Grid2D g(33, kHalfWidth);
  const KernelTable K(g);
  for (int b = -4; b <= 4; ++b)
    for (int a = -4; a <= 4; ++a)
      EXPECT_NEAR(K(a, b) / cell_kernel(a * g.h(), b * g.h(), g.h()), 1.0, 1e-13);
}

// ---------------------------------------------------------------- FFT vs direct

class FftVsDirect : public ::testing::TestWithParam<int> {};

TEST_P(FftVsDirect, RandomPressure) {
  const Grid2D g(GetParam(), kHalfWidth);
  std::mt19937 rng(20221);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  DirectDeformation direct(g);
  FftDeformation fft(g);
  EXPECT_GE(fft.padded_size(), 2 * (g.n - 1));
  EXPECT_EQ(fft.padded_size() % 2, 0);
  Field Wd, Wf;
  // Twice with different data: the second apply must not see the first's
  // leftovers in the work buffers.  Boundary points get pressure too: the
  // operator sums over all points.
  for (int round = 0; round < 2; ++round) {
    Field P(g);
    for (std::size_t k = 0; k < P.size(); ++k) P[k] = uniform(rng);
    direct.apply(P, Wd);
    fft.apply(P, Wf);
    // FFT round-off is ~ eps log2(m^2) relative to max|W| (measured ~1e-15).
    EXPECT_LT(max_diff(Wf, Wd) / max_abs(Wd), 1e-12) << "round " << round;
  }
}

// Powers of two plus one, and n = 21 (m = 40) and 23 (2n-2 = 44 = 4 * 11 is not
// 7-smooth: m = 48 > 2n - 1, the padding is then strictly larger).
// 129: from this size on the transforms are cut into batches that the threads share.
INSTANTIATE_TEST_SUITE_P(Sizes, FftVsDirect, ::testing::Values(17, 21, 23, 33, 65, 129));

TEST(FftVsDirect, SameBitsOnAnyNumberOfThreads) {
  // From 129^2 on the transforms run in a fixed number of batches, shared by
  // the threads of the team: 1, 2 and 3 threads (uneven shares) must give
  // the same bits, full and mirrored grid alike, and agree with the direct sum.
  for (const bool mirrored : {false, true}) {
    const Grid2D g(129, kHalfWidth, mirrored);
    std::mt19937 rng(2022);
    std::uniform_real_distribution<double> uniform(0.0, 1.0);
    Field P(g);
    for (std::size_t k = 0; k < P.size(); ++k) P[k] = uniform(rng);
    Field Wd;
    if (!mirrored) {
      DirectDeformation direct(g);
      direct.apply(P, Wd);
    }
    const int threads_before = omp_get_max_threads();
    Field W1;
    for (const int threads : {1, 2, 3}) {
      omp_set_num_threads(threads);
      FftDeformation fft(g, FftPlanning::Estimate);
      Field Wf;
      fft.apply(P, Wf);
      if (threads == 1) W1 = Wf;
      EXPECT_EQ(max_diff(Wf, W1), 0.0) << threads << " threads, mirrored " << mirrored;
      if (!mirrored) {
        EXPECT_LT(max_diff(Wf, Wd) / max_abs(Wd), 1e-12) << threads << " threads";
      }
    }
    omp_set_num_threads(threads_before);
  }
}

// ------------------------------------------------------- mirrored (quadrant) grids

class MirroredDeformation : public ::testing::TestWithParam<int> {};

TEST_P(MirroredDeformation, EqualsTheFullGridOfTheUnfoldedPressure) {
  // A pressure even in X and Y on the full grid of n points, and its quadrant:
  // the quadrant's deformation (direct sum over the images, and the DCT-I
  // transform) equals the quadrant of the full grid's direct sum to rounding.
  const Grid2D full(GetParam(), kHalfWidth);
  const Grid2D quadrant = full.quadrant();
  ASSERT_EQ(quadrant.full().n, full.n);
  ASSERT_DOUBLE_EQ(quadrant.h(), full.h());
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  Field Pq(quadrant);
  for (std::size_t k = 0; k < Pq.size(); ++k) Pq[k] = uniform(rng);
  const Field P = unfold(Pq, quadrant);
  Field W;
  DirectDeformation(full).apply(P, W);
  const Field expected = fold(W, quadrant);
  Field Wd, Wf;
  DirectDeformation(quadrant).apply(Pq, Wd);
  FftDeformation fft(quadrant);
  EXPECT_EQ(fft.padded_size(), FftDeformation(full).padded_size());
  fft.apply(Pq, Wf);
  EXPECT_LT(max_diff(Wd, expected) / max_abs(expected), 1e-13);
  EXPECT_LT(max_diff(Wf, expected) / max_abs(expected), 1e-12);
  // A second evaluation must not see the first one's leftovers.
  Pq.fill(0.0);
  Pq(0, 0) = 1.0;
  fft.apply(Pq, Wf);
  EXPECT_NEAR(Wf(0, 0), fft.kernel()(0, 0), 1e-14);
  EXPECT_NEAR(Wf(3, 2), fft.kernel()(3, 2), 1e-14);
}

TEST(MirroredDeformation, APressureInACornerBoxNeedsOnlyItsBoxAndLeavesNoTrace) {
  // The transforms of the input look only at the box of the quadrant that
  // holds the pressure (the cavitated rest is zero).  After a pressure over
  // the whole quadrant (which fills every work row), pressures in boxes that
  // end inside a chunk of rows and of columns, and a zero pressure, must
  // still give the direct sum.
  const Grid2D quadrant = Grid2D(257, kHalfWidth).quadrant();
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  DirectDeformation direct(quadrant);
  FftDeformation fft(quadrant);
  const struct { int columns, rows; } boxes[] = {{129, 129}, {37, 21}, {3, 90}, {129, 1}, {0, 0}};
  for (const auto& box : boxes) {
    Field P(quadrant);
    for (int j = 0; j < box.rows; ++j)
      for (int i = 0; i < box.columns; ++i) P(i, j) = uniform(rng);
    Field Wd, Wf;
    direct.apply(P, Wd);
    fft.apply(P, Wf);
    if (box.rows == 0) {
      EXPECT_EQ(max_abs(Wf), 0.0);
    } else {
      EXPECT_LT(max_diff(Wf, Wd) / max_abs(Wd), 1e-12) << box.columns << " x " << box.rows;
    }
  }
}

TEST(MirroredDeformation, HertzPressureGivesTheAnalyticDeformation) {
  // model.md: W = 1 - r^2/2 inside the unit Hertz contact.
  const Grid2D quadrant = Grid2D(201, kHalfWidth).quadrant();
  const Field P = sample(quadrant, hertz_pressure);
  Field W;
  FftDeformation(quadrant).apply(P, W);
  EXPECT_NEAR(W(0, 0), hertz_deformation(0.0), 1e-4);
  const int i = 100;  // X = 1.5
  EXPECT_NEAR(W(i, 0), hertz_deformation(quadrant.x(i)), 1e-4);
}

INSTANTIATE_TEST_SUITE_P(Sizes, MirroredDeformation, ::testing::Values(9, 17, 33, 65, 129));

TEST(Deformation, PointLoadGivesKernelIncludingLargestOffset) {
  // A unit load at a corner: W(i, j) = K(i, j) exactly.  W at the opposite
  // corner uses the offset n - 1, the slot the periodic kernel shares between
  // +(n-1) and -(n-1) when m = 2(n-1).
  for (const int n : {17, 23}) {
    const Grid2D g(n, kHalfWidth);
    Field P(g);
    P(0, 0) = 1.0;
    for (const bool use_fft : {false, true}) {
      auto op = make_deformation(g, use_fft);
      Field W;
      op->apply(P, W);
      const double scale = op->kernel()(0, 0);
      for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i)
          ASSERT_NEAR(W(i, j), op->kernel()(i, j), 1e-14 * scale)
              << "n " << n << (use_fft ? " fft" : " direct") << " at " << i << ", " << j;
    }
  }
}

TEST(Deformation, RejectsMismatchedFields) {
  const Grid2D g(17, kHalfWidth);
  FftDeformation fft(g, FftPlanning::Estimate);
  Field P(g), W(Grid2D(9, kHalfWidth));
  fft.apply(P, W);  // W is re-created on the operator's grid
  EXPECT_EQ(W.n(), 17);
  Field wrong(Grid2D(9, kHalfWidth));
  EXPECT_THROW(fft.apply(wrong, W), std::invalid_argument);
  EXPECT_THROW(fft.apply(P, P), std::invalid_argument);
}

// ---------------------------------------------------------------- analytic solutions

TEST(Deformation, HertzPressureOn201Grid) {
  // model.md: P = sqrt(1 - r^2) on 201^2 points over [-1.5, 1.5]^2 gives
  // W(0) ~ 1 and W(1.5) ~ 0.297811.  Measured here: 0.9999953 and 0.2978252.
  // model.md quotes 0.99998 and 0.297798 (errors -2e-5 and -1.3e-5); those
  // digits could not be reproduced with this grid convention.  The point error
  // is not a smooth function of h: the sqrt edge at r = 1 makes it depend on
  // how the circle cuts the lattice, and over n = 195..207 it ranges up to
  // 1e-4 (~0.5 h^2).  2e-5 bounds the error on this grid and the model.md values.
  const Grid2D g(201, kHalfWidth);
  const Field P = sample(g, hertz_pressure);
  FftDeformation fft(g);
  Field W;
  fft.apply(P, W);
  const int c = (g.n - 1) / 2;
  EXPECT_NEAR(W(c, c), 1.0, 2e-5);
  EXPECT_NEAR(W(g.n - 1, c), hertz_deformation(1.5), 2e-5);
  // The same two values by direct point sums (no FFT involved).
  double w0 = 0.0, w15 = 0.0;
  for (int j = 0; j < g.n; ++j)
    for (int i = 0; i < g.n; ++i) {
      w0 += fft.kernel()(i - c, j - c) * P(i, j);
      w15 += fft.kernel()(i - (g.n - 1), j - c) * P(i, j);
    }
  EXPECT_NEAR(W(c, c), w0, 1e-13);
  EXPECT_NEAR(W(g.n - 1, c), w15, 1e-13);
  // Everywhere: the largest error sits at the sqrt edge (measured 2.5e-4).
  double err = 0.0;
  for (int j = 0; j < g.n; ++j)
    for (int i = 0; i < g.n; ++i)
      err = std::max(err, std::fabs(W(i, j) - hertz_deformation(std::hypot(g.x(i), g.y(j)))));
  EXPECT_LT(err, 4e-4);
}

TEST(Deformation, SecondOrderConvergence) {
  // Piecewise-constant pressure with the exact cell kernel is a midpoint rule:
  // O(h^2) for a smooth pressure.  The Hertz pressure's sqrt edge adds an
  // error that fluctuates with how the circle cuts the lattice (observed
  // orders 1.1..2.8 between successive grids), so the order is measured on
  // P = (1 - r^2)^(3/2), whose edge term is O(h^3).  Max norm over all grid
  // points (the maximum sits at the centre); measured orders 1.85, 2.01, 1.97.
  std::vector<double> errors;
  for (const int n : {33, 65, 129, 257}) {
    const Grid2D g(n, kHalfWidth);
    FftDeformation fft(g, FftPlanning::Estimate);
    Field W;
    fft.apply(sample(g, smooth_pressure), W);
    double err = 0.0;
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i)
        err = std::max(err, std::fabs(W(i, j) - smooth_deformation(std::hypot(g.x(i), g.y(j)))));
    errors.push_back(err);
  }
  for (std::size_t k = 0; k + 1 < errors.size(); ++k) {
    const double order = std::log2(errors[k] / errors[k + 1]);
    EXPECT_GE(order, 1.7) << "between grids " << k << " and " << k + 1;
    EXPECT_LE(order, 2.3) << "between grids " << k << " and " << k + 1;
  }
  EXPECT_LT(errors.back(), 2e-5);  // measured 1.7e-5 on 257^2
}
