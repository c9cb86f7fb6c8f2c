#include "elastic/Deformation.hpp"

#include <fftw3.h>
#include <omp.h>

#include <algorithm>
#include <cstring>
#include <memory>
#include <mutex>
#include <new>
#include <stdexcept>
#include <vector>

namespace ehlsim {

void DeformationOperator::prepare(const Field& P, Field& W) const {
  if (&P == &W) throw std::invalid_argument("DeformationOperator::apply: P and W must differ");
  if (P.n() != grid_.n || P.size() != grid_.size())
    throw std::invalid_argument("DeformationOperator::apply: P is not on the operator's grid");
  if (W.n() != grid_.n || W.size() != grid_.size()) W = Field(grid_);
}

// ---------------------------------------------------------------------------
// Direct sum

void DirectDeformation::apply(const Field& P, Field& W) {
  prepare(P, W);
  const int n = grid().n;
  const double* K = kernel().data();
  const double* p = P.data();
  double* w = W.data();
  const auto row = [n](int j) { return static_cast<std::size_t>(j) * n; };

  // Rows of P that are entirely zero (the boundary, the cavitated region)
  // contribute nothing; skipping them is exact.
  std::vector<char> nonzero(static_cast<std::size_t>(n), 0);
  for (int l = 0; l < n; ++l)
    nonzero[l] = std::any_of(p + row(l), p + row(l) + n, [](double v) { return v != 0.0; });

  std::fill(w, w + W.size(), 0.0);
  for (int j = 0; j < n; ++j) {
    double* wj = w + row(j);
    for (int l = 0; l < n; ++l) {
      if (!nonzero[l]) continue;
      const double* Kr = K + row(j > l ? j - l : l - j);
      const double* pl = p + row(l);
      for (int i = 0; i < n; ++i) {
        double s = 0.0;
        for (int k = 0; k <= i; ++k) s += Kr[i - k] * pl[k];
        for (int k = i + 1; k < n; ++k) s += Kr[k - i] * pl[k];
        wj[i] += s;
      }
    }
  }
}

// ---------------------------------------------------------------------------
// FFT convolution

namespace {

/// FFTW's planner has global state and is not thread-safe: every plan
/// creation and destruction done here is serialised.
std::mutex& fftw_planner_mutex() {
  static std::mutex m;
  return m;
}

struct PlanDeleter {
  void operator()(fftw_plan_s* plan) const {
    const std::lock_guard lock(fftw_planner_mutex());
    fftw_destroy_plan(plan);
  }
};
using Plan = std::unique_ptr<fftw_plan_s, PlanDeleter>;

/// Runs the planner call `create` under the planner mutex; throws on failure.
template <class Create>
Plan make_plan(Create&& create) {
  fftw_plan plan = nullptr;
  {
    const std::lock_guard lock(fftw_planner_mutex());
    plan = create();
  }
  if (plan == nullptr) throw std::runtime_error("FftDeformation: FFTW could not create a plan");
  return Plan(plan);
}

struct FftwFree {
  void operator()(void* p) const { fftw_free(p); }
};
template <class T>
using FftwBuffer = std::unique_ptr<T[], FftwFree>;

template <class T>
FftwBuffer<T> fftw_buffer(std::size_t count) {
  auto* p = static_cast<T*>(fftw_malloc(sizeof(T) * count));
  if (p == nullptr) throw std::bad_alloc();
  return FftwBuffer<T>(p);
}

/// Smallest even m >= lower (lower even) with no prime factor above 7: the
/// sizes FFTW handles fastest.  Even, because the kernel transform is a DCT-I
/// of size m/2 + 1, which is the DFT of an even sequence of period m only for
/// even m.
int padded_period(int lower) {
  for (int m = lower + lower % 2;; m += 2) {
    int r = m;
    for (const int f : {2, 3, 5, 7})
      while (r % f == 0) r /= f;
    if (r == 1) return m;
  }
}

/// Grids with fewer points per side than this transform in one batch: the
/// cost of sharing out the work exceeds the transform (measured: 65^2 takes
/// about 0.1 ms).
constexpr int kMinPointsForBatches = 129;
/// The transforms of larger grids are cut into this many batches, whatever the
/// number of threads: the arithmetic, and with it every bit of the result,
/// then does not depend on how many threads share the batches.
constexpr int kBatches = 8;

/// The half-open range [begin, end) of part `c` of `parts` equal shares of `count`.
struct Share {
  int begin, end;
};
Share share(int count, int parts, int c) {
  return {count * c / parts, count * (c + 1) / parts};
}

}  // namespace

struct FftDeformation::Impl {
  int n;        // grid points per side
  int m;        // padded period per side
  int mc;       // m/2 + 1: complex columns of the r2c transform, also the kernel quarter size
  int parts;    // the transforms are cut into this many independent batches, one per thread
  FftwBuffer<double> real;           // n rows of m: P in, W out
  FftwBuffer<fftw_complex> spectrum; // m rows of mc
  FftwBuffer<double> kernel_hat;     // mc rows of mc: real kernel transform / m^2, ky <= m/2
  // One plan per batch: rows of the real array, columns of the spectrum.  A
  // 2-D transform is a batch of 1-D transforms along each axis, so the
  // batches of one axis are independent and run on the threads of the
  // calling OpenMP team (FFTW's own threads cost more than they save at these
  // sizes: docs/performance.md).
  std::vector<Plan> rows_forward, cols_forward, cols_backward, rows_backward;

  Impl(const KernelTable& K, FftPlanning planning)
      : n(K.n()),
        m(padded_period(2 * (K.n() - 1))),
        mc(m / 2 + 1),
        parts(K.n() >= kMinPointsForBatches ? kBatches : 1),
        real(fftw_buffer<double>(static_cast<std::size_t>(n) * m)),
        spectrum(fftw_buffer<fftw_complex>(static_cast<std::size_t>(m) * mc)),
        kernel_hat(fftw_buffer<double>(static_cast<std::size_t>(mc) * mc)) {
    const unsigned flags = planning == FftPlanning::Measure ? FFTW_MEASURE : FFTW_ESTIMATE;
    for (int c = 0; c < parts; ++c) {
      // Rows [r.begin, r.end): real transforms of length m, row stride m in, mc out.
      const Share r = share(n, parts, c);
      double* row_in = real.get() + static_cast<std::size_t>(r.begin) * m;
      fftw_complex* row_out = spectrum.get() + static_cast<std::size_t>(r.begin) * mc;
      const int rows = r.end - r.begin;
      rows_forward.push_back(make_plan([&] {
        return fftw_plan_many_dft_r2c(1, &m, rows, row_in, nullptr, 1, m, row_out, nullptr, 1, mc,
                                      flags);
      }));
      rows_backward.push_back(make_plan([&] {
        return fftw_plan_many_dft_c2r(1, &m, rows, row_out, nullptr, 1, mc, row_in, nullptr, 1, m,
                                      flags);
      }));
      // Columns [k.begin, k.end): complex transforms of length m, in place, element stride mc.
      const Share k = share(mc, parts, c);
      fftw_complex* col = spectrum.get() + k.begin;
      const int cols = k.end - k.begin;
      cols_forward.push_back(make_plan([&] {
        return fftw_plan_many_dft(1, &m, cols, col, nullptr, mc, 1, col, nullptr, mc, 1,
                                  FFTW_FORWARD, flags);
      }));
      cols_backward.push_back(make_plan([&] {
        return fftw_plan_many_dft(1, &m, cols, col, nullptr, mc, 1, col, nullptr, mc, 1,
                                  FFTW_BACKWARD, flags);
      }));
    }

    // Kernel transform.  The periodic kernel is the even extension of
    // K(a, b), a, b = 0..m/2 (zero for a or b >= n), so its DFT is real and
    // equals the 2-D DCT-I (REDFT00) of that (m/2 + 1)^2 array.
    double* kh = kernel_hat.get();
    for (int b = 0; b < mc; ++b)
      for (int a = 0; a < mc; ++a)
        kh[static_cast<std::size_t>(b) * mc + a] = (a < n && b < n) ? K(a, b) : 0.0;
    // ESTIMATE: a one-off transform, and it leaves the filled array intact.
    const Plan dct = make_plan(
        [&] { return fftw_plan_r2r_2d(mc, mc, kh, kh, FFTW_REDFT00, FFTW_REDFT00, FFTW_ESTIMATE); });
    fftw_execute(dct.get());
    // Fold the 1/m^2 of the unnormalised inverse transform into the kernel.
    const double scale = 1.0 / (static_cast<double>(m) * m);
    for (std::size_t k = 0; k < static_cast<std::size_t>(mc) * mc; ++k) kh[k] *= scale;
  }

  void apply(const double* p, double* w) {
    const auto un = static_cast<std::size_t>(n);
    const auto um = static_cast<std::size_t>(m);
    const auto umc = static_cast<std::size_t>(mc);
    double* r = real.get();
    fftw_complex* s = spectrum.get();
    const double* kh = kernel_hat.get();

    // Three stages, each a loop over the batches; a stage reads what the one
    // before wrote across all batches, so each ends in its loop's barrier.
    // Within a stage a batch's steps touch only its own rows or columns, so
    // they need no barrier between them.  (Fewer barriers, less waiting: in
    // a default run, libgomp's waiting at barriers took 13 % of the samples.)
#pragma omp parallel if (parts > 1)
    {
      // Rows: P into the first n columns of the batch's data rows, zero
      // padding after, then their real transforms.  The batch also clears its
      // share of the spectrum's padding rows (overwritten by the previous
      // inverse transform).
#pragma omp for schedule(static)
      for (int c = 0; c < parts; ++c) {
        const Share rows = share(n, parts, c);
        for (auto j = static_cast<std::size_t>(rows.begin); j < static_cast<std::size_t>(rows.end); ++j) {
          std::copy_n(p + j * un, un, r + j * um);
          std::fill(r + j * um + un, r + (j + 1) * um, 0.0);
        }
        const Share padding = share(m - n, parts, c);
        std::memset(static_cast<void*>(s + (un + padding.begin) * umc), 0,
                    sizeof(fftw_complex) * umc * (padding.end - padding.begin));
        fftw_execute(rows_forward[c].get());
      }
      // Columns: forward transform, product with the kernel transform (even
      // in ky), inverse transform.
#pragma omp for schedule(static)
      for (int c = 0; c < parts; ++c) {
        fftw_execute(cols_forward[c].get());
        const Share cols = share(mc, parts, c);
        for (std::size_t ky = 0; ky < um; ++ky) {
          const double* k = kh + std::min(ky, um - ky) * umc;
          fftw_complex* row = s + ky * umc;
          for (auto kx = static_cast<std::size_t>(cols.begin); kx < static_cast<std::size_t>(cols.end); ++kx) {
            row[kx][0] *= k[kx];
            row[kx][1] *= k[kx];
          }
        }
        fftw_execute(cols_backward[c].get());
      }
      // Rows: inverse real transforms, W out of the first n columns.
#pragma omp for schedule(static)
      for (int c = 0; c < parts; ++c) {
        fftw_execute(rows_backward[c].get());
        const Share rows = share(n, parts, c);
        for (auto j = static_cast<std::size_t>(rows.begin); j < static_cast<std::size_t>(rows.end); ++j)
          std::copy_n(r + j * um, un, w + j * un);
      }
    }
  }
};

FftDeformation::FftDeformation(const Grid2D& grid, FftPlanning planning)
    : DeformationOperator(grid), impl_(std::make_unique<Impl>(kernel(), planning)) {}

FftDeformation::~FftDeformation() = default;

void FftDeformation::apply(const Field& P, Field& W) {
  prepare(P, W);
  impl_->apply(P.data(), W.data());
}

int FftDeformation::padded_size() const { return impl_->m; }

std::unique_ptr<DeformationOperator> make_deformation(const Grid2D& grid, bool use_fft) {
  if (use_fft) return std::make_unique<FftDeformation>(grid, FftPlanning::Estimate);
  return std::make_unique<DirectDeformation>(grid);
}

}  // namespace ehlsim
