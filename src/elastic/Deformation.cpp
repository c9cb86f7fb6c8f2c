#include "elastic/Deformation.hpp"

#include <fftw3.h>
#include <omp.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <memory>
#include <mutex>
#include <new>
#include <numbers>
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

namespace {
/// The direct sum on a mirrored grid: each quadrant point (k, l) stands for
/// its images (+-k, +-l) of the full grid, and the kernel table covers the
/// full grid's offsets.
void direct_sum_mirrored(const KernelTable& K, const Field& P, Field& W) {
  const int n = P.n();
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      double w = 0.0;
      for (int l = 0; l < n; ++l) {
        for (int k = 0; k < n; ++k) {
          const double p = P(k, l);
          if (p == 0.0) continue;
          double kernel = K(i - k, j - l);
          if (k > 0) kernel += K(i + k, j - l);
          if (l > 0) kernel += K(i - k, j + l);
          if (k > 0 && l > 0) kernel += K(i + k, j + l);
          w += kernel * p;
        }
      }
      W(i, j) = w;
    }
  }
}
}  // namespace

void DirectDeformation::apply(const Field& P, Field& W) {
  prepare(P, W);
  if (grid().mirrored) {
    direct_sum_mirrored(kernel(), P, W);
    return;
  }
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
Share share(int count, int parts, int c) { return {count * c / parts, count * (c + 1) / parts}; }

}  // namespace

/// The transform engine of FftDeformation: full or mirrored grid.
struct FftDeformation::Impl {
  Impl() = default;
  Impl(const Impl&) = delete;
  Impl& operator=(const Impl&) = delete;
  Impl(Impl&&) = delete;
  Impl& operator=(Impl&&) = delete;
  virtual ~Impl() = default;
  /// w = K * p, both on the operator's grid (n^2 points, row-major).
  virtual void apply(const double* p, double* w) = 0;
  int m = 0;  ///< the padded period per side (of the full grid)
};

namespace {

/// The transform of the padded periodic kernel, real because the kernel is
/// even: the 2-D DCT-I (REDFT00) of K(a, b), a, b = 0..m/2 (zero beyond the
/// table), (m/2 + 1)^2 values, with the 1/m^2 of the unnormalised inverse
/// transform folded in.
FftwBuffer<double> kernel_spectrum(const KernelTable& K, int m) {
  const int mc = m / 2 + 1;
  const int n = K.n();
  auto spectrum = fftw_buffer<double>(static_cast<std::size_t>(mc) * mc);
  double* kh = spectrum.get();
  for (int b = 0; b < mc; ++b)
    for (int a = 0; a < mc; ++a)
      kh[static_cast<std::size_t>(b) * mc + a] = (a < n && b < n) ? K(a, b) : 0.0;
  // ESTIMATE: a one-off transform, and it leaves the filled array intact.
  const Plan dct = make_plan(
      [&] { return fftw_plan_r2r_2d(mc, mc, kh, kh, FFTW_REDFT00, FFTW_REDFT00, FFTW_ESTIMATE); });
  fftw_execute(dct.get());
  const double scale = 1.0 / (static_cast<double>(m) * m);
  for (std::size_t k = 0; k < static_cast<std::size_t>(mc) * mc; ++k) kh[k] *= scale;
  return spectrum;
}

unsigned planner_flags(FftPlanning planning) {
  return planning == FftPlanning::Measure ? FFTW_MEASURE : FFTW_ESTIMATE;
}

/// Number of batches the transforms of an n-point grid are cut into.
int batch_count(int n) { return n >= kMinPointsForBatches ? kBatches : 1; }

/// Runs a 2-D transform convolution as three stages, each a loop over the
/// batches: along X (P in, forward), along Y (forward, product with the
/// kernel spectrum, inverse), along X (inverse, W out).  A stage reads what the
/// one before wrote across all batches, so each ends in its loop's barrier;
/// within a stage a batch touches only its own rows or columns.  (Fewer
/// barriers, less waiting: libgomp's waiting at barriers took 13 % of the
/// samples of a default run when each transform had its own.)
template <class RowsIn, class Columns, class RowsOut>
void in_three_stages(int parts, RowsIn&& rows_in, Columns&& columns, RowsOut&& rows_out) {
#pragma omp parallel if (parts > 1)
  {
#pragma omp for schedule(static)
    for (int c = 0; c < parts; ++c) rows_in(c);
#pragma omp for schedule(static)
    for (int c = 0; c < parts; ++c) columns(c);
#pragma omp for schedule(static)
    for (int c = 0; c < parts; ++c) rows_out(c);
  }
}

/// Calls chunk(first, count) for the chunks of at most `size` of the range r.
template <class Chunk>
void by_chunks_of(int size, Share r, Chunk&& chunk) {
  for (int first = r.begin; first < r.end; first += size)
    chunk(first, std::min(size, r.end - first));
}

/// The full grid: r2c transforms of the n data rows (period m), c2c
/// transforms of the m/2 + 1 spectral columns, product with the kernel
/// spectrum, and back.  The all-zero padding rows are never transformed
/// along X, and along Y they are zeros in a strip: about a quarter of the
/// work of a plain 2-D transform is skipped.  The columns go through the
/// transforms along Y a few at a time, copied into a contiguous strip, as
/// the mirrored grid's do: transforms down columns of the n x mc spectrum
/// (a stride of 16 kB on 1025^2) took twice the time per point of the
/// mirrored grid's (docs/performance.md).
struct FullImpl final : FftDeformation::Impl {
  /// Spectral columns per strip: 8 columns of 2048 complex values (1025^2)
  /// are 256 kB, which stay in the L2 cache through both transforms.
  static constexpr int kColumnChunk = 8;
  /// One batch's strip of columns and the transforms of 1..kColumnChunk of
  /// them (contiguous, period m each).
  struct Strip {
    FftwBuffer<fftw_complex> values;      // kColumnChunk columns of m
    std::vector<Plan> forward, backward;  // [count - 1]
  };
  int n;      // grid points per side
  int mc;     // m/2 + 1: complex columns of the r2c transform, also the kernel quarter size
  int parts;  // the transforms are cut into this many independent batches
  FftwBuffer<double> real;            // n rows of m: P in, W out
  FftwBuffer<fftw_complex> spectrum;  // n rows of mc: the data rows' transforms
  FftwBuffer<double> kernel_hat;      // mc rows of mc: the kernel spectrum (symmetric)
  // One plan per batch for the rows of the real array; the strips' plans per
  // batch.  A 2-D transform is a batch of 1-D transforms along each axis, so
  // the batches of one axis are independent and run on the threads of the
  // calling OpenMP team (FFTW's own threads cost more than they save at these
  // sizes: docs/performance.md).
  std::vector<Plan> rows_forward, rows_backward;
  std::vector<Strip> strips;

  FullImpl(const KernelTable& K, FftPlanning planning)
      : n(K.n()),
        mc(padded_period(2 * (K.n() - 1)) / 2 + 1),
        parts(batch_count(K.n())),
        real(fftw_buffer<double>(static_cast<std::size_t>(n) * 2 * (mc - 1))),
        spectrum(fftw_buffer<fftw_complex>(static_cast<std::size_t>(n) * mc)),
        kernel_hat(kernel_spectrum(K, 2 * (mc - 1))) {
    m = 2 * (mc - 1);
    const unsigned flags = planner_flags(planning);
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
      strips.push_back(make_strip(flags));
    }
  }

  [[nodiscard]] Strip make_strip(unsigned flags) const {
    Strip strip{fftw_buffer<fftw_complex>(static_cast<std::size_t>(kColumnChunk) * m), {}, {}};
    fftw_complex* v = strip.values.get();
    for (int count = 1; count <= kColumnChunk; ++count) {
      strip.forward.push_back(make_plan([&] {
        return fftw_plan_many_dft(1, &m, count, v, nullptr, 1, m, v, nullptr, 1, m, FFTW_FORWARD,
                                  flags);
      }));
      strip.backward.push_back(make_plan([&] {
        return fftw_plan_many_dft(1, &m, count, v, nullptr, 1, m, v, nullptr, 1, m, FFTW_BACKWARD,
                                  flags);
      }));
    }
    return strip;
  }

  /// Columns first .. first + count - 1 of the spectrum along Y: into the
  /// strip (zero beyond the n data rows), forward, product with the kernel
  /// spectrum (even in ky, and symmetric: row kx holds the column kx), inverse,
  /// and the n data rows back (the inverse along X needs no others).
  void columns_along_y(Strip& strip, int first, int count) {
    const auto um = static_cast<std::size_t>(m);
    const auto umc = static_cast<std::size_t>(mc);
    const auto un = static_cast<std::size_t>(n);
    const auto uc = static_cast<std::size_t>(count);
    fftw_complex* s = spectrum.get() + first;
    fftw_complex* v = strip.values.get();
    for (std::size_t ky = 0; ky < un; ++ky)
      for (std::size_t col = 0; col < uc; ++col) {
        v[col * um + ky][0] = s[ky * umc + col][0];
        v[col * um + ky][1] = s[ky * umc + col][1];
      }
    for (std::size_t col = 0; col < uc; ++col)
      std::memset(static_cast<void*>(v + col * um + un), 0, sizeof(fftw_complex) * (um - un));
    fftw_execute(strip.forward[uc - 1].get());
    for (std::size_t col = 0; col < uc; ++col) {
      const double* kernel_row = kernel_hat.get() + (first + col) * umc;
      fftw_complex* column = v + col * um;
      for (std::size_t ky = 0; ky < um; ++ky) {
        const double k = kernel_row[std::min(ky, um - ky)];
        column[ky][0] *= k;
        column[ky][1] *= k;
      }
    }
    fftw_execute(strip.backward[uc - 1].get());
    for (std::size_t ky = 0; ky < un; ++ky)
      for (std::size_t col = 0; col < uc; ++col) {
        s[ky * umc + col][0] = v[col * um + ky][0];
        s[ky * umc + col][1] = v[col * um + ky][1];
      }
  }

  void apply(const double* p, double* w) override {
    const auto un = static_cast<std::size_t>(n);
    const auto um = static_cast<std::size_t>(m);
    double* r = real.get();
    // P into the first n columns of the batch's data rows, zero padding
    // after, then their real transforms.
    const auto rows_in = [&](int c) {
      const Share rows = share(n, parts, c);
      for (auto j = static_cast<std::size_t>(rows.begin); j < static_cast<std::size_t>(rows.end);
           ++j) {
        std::copy_n(p + j * un, un, r + j * um);
        std::fill(r + j * um + un, r + (j + 1) * um, 0.0);
      }
      fftw_execute(rows_forward[c].get());
    };
    const auto columns = [&](int c) {
      by_chunks_of(kColumnChunk, share(mc, parts, c),
                   [&](int first, int count) { columns_along_y(strips[c], first, count); });
    };
    // Inverse real transforms, W out of the first n columns.
    const auto rows_out = [&](int c) {
      fftw_execute(rows_backward[c].get());
      const Share rows = share(n, parts, c);
      for (auto j = static_cast<std::size_t>(rows.begin); j < static_cast<std::size_t>(rows.end);
           ++j)
        std::copy_n(r + j * um, un, w + j * un);
    };
    in_three_stages(parts, rows_in, columns, rows_out);
  }
};

/// DCT-I (FFTW's REDFT00, unnormalised: Y_k = x_0 + (-1)^k x_M +
/// 2 sum_{j=1}^{M-1} x_j cos(pi j k / M)) of up to kChunk contiguous vectors
/// of M + 1 values, x[v * dist + j], in place, through one real DFT of size M
/// per vector.  FFTW's own REDFT00 pads to a real DFT of size 2M and took
/// 3.4 times as long as a real DFT of size M (M = 256, 257 vectors).
///
/// With a_j = x_j + x_{M-j} (even in j) and b_j = x_j - x_{M-j} (odd), the
/// sequence u_j = a_j + sin(pi j / M) b_j (j < M) has the DFT U_q with
///   Re U_q = sum a_j cos(2 pi j q / M)          = Y_{2q},
///   Im U_q = -sum b_j sin(pi j/M) sin(2 pi j q/M) = (Y_{2q+1} - Y_{2q-1}) / 2,
/// the second from cos((2q+1)t) - cos((2q-1)t) = -2 sin t sin(2qt); the odd
/// outputs follow from Y_1 = sum b_j cos(pi j / M) by that recurrence.  The
/// real DFT writes U straight into the vector (dist >= M + 2: U has M/2 + 1
/// complex values), where Re U_q already sits at x_{2q} and Im U_q at x_{2q+1}.
///
/// A few vectors at a time: their values, u and the spectrum (about 130 kB
/// for M = 1024) stay in the L2 cache from the preparation through the real
/// DFT to the recurrence, and the caller's work on the chunk before and after
/// (copies, transposes, the kernel product) finds them there too.  Whole
/// batches of 64-128 vectors went through memory at every pass: the passes
/// around FFTW then took more time than FFTW itself (docs/performance.md).
class DctI {
 public:
  /// Vectors per call at most.
  static constexpr int kChunk = 8;
  /// Row stride a vector needs.
  static int stride_for(int M) { return M + 2; }

  DctI(int M, int dist, unsigned flags)
      : M_(M),
        dist_(dist),
        u_(fftw_buffer<double>(static_cast<std::size_t>(M) * kChunk)),
        sin_(static_cast<std::size_t>(M)),
        cos_(static_cast<std::size_t>(M)) {
    if (dist < stride_for(M)) throw std::invalid_argument("DctI: rows too short for the spectrum");
    for (int j = 0; j < M; ++j) {
      const double t = std::numbers::pi * j / M;
      sin_[j] = std::sin(t);
      cos_[j] = std::cos(t);
    }
    // The plans are made for one array of vectors: apply() must pass arrays
    // with the same alignment (fftw_malloc'ed, dist even).  One plan per count
    // of vectors, so that a vector's arithmetic depends only on the count of
    // its chunk, which the grid fixes.
    auto probe = fftw_buffer<double>(static_cast<std::size_t>(dist) * kChunk);
    const int out_dist = dist / 2;
    for (int count = 1; count <= kChunk; ++count)
      plans_.push_back(make_plan([&] {
        return fftw_plan_many_dft_r2c(1, &M_, count, u_.get(), nullptr, 1, M,
                                      reinterpret_cast<fftw_complex*>(probe.get()), nullptr, 1,
                                      out_dist, flags | FFTW_DESTROY_INPUT);
      }));
  }

  /// Transforms the `count` (<= kChunk) vectors at x in place.
  void apply(double* x, int count) {
    std::array<double, kChunk> y1{};
    for (int v = 0; v < count; ++v) {
      const double* __restrict xv = x + static_cast<std::size_t>(v) * dist_;
      Sums s;
      prepare(
          0, M_, v, [&](int j) { return xv[j]; }, [&](int j) { return xv[M_ - j]; }, s);
      y1[v] = s.total();
    }
    finish(x, count, y1);
  }

  /// Transforms the `count` (<= kChunk) vectors whose first `values`
  /// (<= M) values are those of the rows of `src` (stride src_dist) and the
  /// rest zero; the results go to the vectors at x (which may be src).  The
  /// zeros are neither stored nor read: the forward transforms of the
  /// quadrant have data in the first half of each vector only.
  void apply_padded(const double* src, int src_dist, int values, double* x, int count) {
    // x_j is data for j < values, x_{M-j} for j >= M - values + 1.
    const int a = values, b = M_ - values + 1;
    std::array<double, kChunk> y1{};
    for (int v = 0; v < count; ++v) {
      const double* __restrict sv = src + static_cast<std::size_t>(v) * src_dist;
      const auto data = [&](int j) { return sv[j]; };
      const auto mirror = [&](int j) { return sv[M_ - j]; };
      const auto zero = [](int) { return 0.0; };
      Sums s;
      prepare(0, std::min(a, b), v, data, zero, s);
      if (a <= b)
        prepare(a, b, v, zero, zero, s);
      else
        prepare(b, a, v, data, mirror, s);
      prepare(std::max(a, b), M_, v, zero, mirror, s);
      y1[v] = s.total();
    }
    finish(x, count, y1);
  }

 private:
  /// Y_1 in kPartialSums partial sums, of j = 0, 1, 2, 3 mod 4, each in the
  /// order of j: four independent chains of additions instead of one (a
  /// running sum was 40 % of an evaluation; docs/performance.md).  The order,
  /// and so the bits, follow from this number.
  static constexpr int kPartialSums = 4;
  struct Sums {
    double s[kPartialSums] = {};
    /// ((s[0] + s[1]) + s[2]) + s[3], in that order.
    [[nodiscard]] double total() const {
      double sum = s[0];
      for (int k = 1; k < kPartialSums; ++k) sum += s[k];
      return sum;
    }
  };

  /// u_j of the vector in slot v for j in [j0, j1), and its share of Y_1,
  /// where x(j) is the vector's value x_j and y(j) its value x_{M-j}.
  /// sin(0) = 0 makes u_0 = x_0 + x_M.
  template <class X, class Y>
  void prepare(int j0, int j1, int v, X x, Y y, Sums& sums) {
    double* __restrict uv = u_.get() + static_cast<std::size_t>(v) * M_;
    const double* __restrict sj = sin_.data();
    const double* __restrict cj = cos_.data();
    const auto term = [&](int j, double& partial) {
      const double xj = x(j), yj = y(j);
      const double odd = xj - yj;
      uv[j] = (xj + yj) + sj[j] * odd;
      partial += cj[j] * odd;
    };
    int j = j0;
    for (; j < j1 && j % kPartialSums != 0; ++j) term(j, sums.s[j % kPartialSums]);
    for (; j + kPartialSums <= j1; j += kPartialSums)
      for (int t = 0; t < kPartialSums; ++t) term(j + t, sums.s[t]);
    for (; j < j1; ++j) term(j, sums.s[j % kPartialSums]);
  }

  /// The real DFTs of the prepared u into the vectors at x, and their odd
  /// values from Y_1.
  void finish(double* x, int count, const std::array<double, kChunk>& y1) {
    fftw_execute_dft_r2c(plans_[count - 1].get(), u_.get(), reinterpret_cast<fftw_complex*>(x));
    // x_{2q} = Re U_q is in place; x_{2q+1} = x_{2q-1} + 2 Im U_q, a chain of
    // dependent additions along each vector: four vectors at a time, so that
    // their chains overlap.
    const auto row = [&](int v) { return x + static_cast<std::size_t>(v) * dist_; };
    int v = 0;
    for (; v + 4 <= count; v += 4) {
      double* __restrict a = row(v);
      double* __restrict b = row(v + 1);
      double* __restrict c = row(v + 2);
      double* __restrict d = row(v + 3);
      double ra = y1[v], rb = y1[v + 1], rc = y1[v + 2], rd = y1[v + 3];
      a[1] = ra, b[1] = rb, c[1] = rc, d[1] = rd;
      for (int j = 3; j < M_; j += 2) {
        a[j] = ra = ra + 2.0 * a[j];
        b[j] = rb = rb + 2.0 * b[j];
        c[j] = rc = rc + 2.0 * c[j];
        d[j] = rd = rd + 2.0 * d[j];
      }
    }
    for (; v < count; ++v) {
      double* __restrict a = row(v);
      double ra = y1[v];
      a[1] = ra;
      for (int j = 3; j < M_; j += 2) a[j] = ra = ra + 2.0 * a[j];
    }
  }

  int M_, dist_;
  FftwBuffer<double> u_;
  std::vector<double> sin_, cos_;
  std::vector<Plan> plans_;  // plans_[c - 1]: c vectors
};

/// to[c * to_dist + r] = from[r * from_dist + c] for r < rows, c < cols.
void transpose(const double* __restrict from, int from_dist, double* __restrict to, int to_dist,
               int rows, int cols) {
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c)
      to[static_cast<std::size_t>(c) * to_dist + r] =
          from[static_cast<std::size_t>(r) * from_dist + c];
}

/// The mirrored grid (the quadrant of a pressure even in X and Y).  The
/// even extension of the quadrant with period m (the full grid's padded
/// period) has a real, even DFT: the DCT-I of its m/2 + 1 values per side.
/// So W = DCT-I(Khat . DCT-I(P)) on the (m/2 + 1)^2 array, of which the
/// quadrant holds n rows and columns of data: the row transforms of the
/// forward and the inverse pass run on those n rows only.  The transforms
/// along Y run on a few columns at a time, transposed into a small strip, so
/// that every transform reads contiguous memory.  About a quarter of the
/// full grid's work.
struct MirroredImpl final : FftDeformation::Impl {
  /// One batch's transform and its strip of transposed columns.
  struct Batch {
    DctI dct;
    FftwBuffer<double> strip;  // DctI::kChunk rows of dist
  };
  int n;                          // quadrant points per side
  int mc;                         // m/2 + 1 values per side of the even arrays
  int dist;                       // row stride of the work arrays (room for the DCT's spectrum)
  int parts;                      // batches, as in FullImpl
  FftwBuffer<double> data;        // n rows: the transforms along X
  FftwBuffer<double> kernel_hat;  // mc rows of mc (symmetric: K(a, b) = K(b, a))
  std::vector<Batch> batches;

  MirroredImpl(const KernelTable& K, FftPlanning planning)
      : n((K.n() + 1) / 2),
        mc(padded_period(2 * (K.n() - 1)) / 2 + 1),
        dist(DctI::stride_for(mc - 1)),
        parts(batch_count(K.n())),
        data(fftw_buffer<double>(static_cast<std::size_t>(n) * dist)),
        kernel_hat(kernel_spectrum(K, 2 * (mc - 1))) {
    m = 2 * (mc - 1);
    const unsigned flags = planner_flags(planning);
    batches.reserve(static_cast<std::size_t>(parts));
    for (int c = 0; c < parts; ++c)
      batches.push_back({DctI(mc - 1, dist, flags),
                         fftw_buffer<double>(static_cast<std::size_t>(DctI::kChunk) * dist)});
  }

  /// The box [0, columns) x [0, rows) of the quadrant beyond which P is zero.
  struct Extent {
    int columns, rows;
  };
  /// Reads the zeros only: from the last row down to the first nonzero one,
  /// and in the rows below it from the end to the last nonzero value found.
  [[nodiscard]] Extent pressurized_extent(const double* p) const {
    const auto row = [&](int j) { return p + static_cast<std::size_t>(j) * n; };
    int rows = n;
    while (rows > 0 && std::all_of(row(rows - 1), row(rows - 1) + n, is_zero)) --rows;
    int columns = 0;
    for (int j = 0; j < rows; ++j) {
      int last = n;
      while (last > columns && is_zero(row(j)[last - 1])) --last;
      columns = last;
    }
    return {columns, rows};
  }
  static bool is_zero(double value) { return value == 0.0; }

  void apply(const double* p, double* w) override {
    const auto un = static_cast<std::size_t>(n);
    const auto umc = static_cast<std::size_t>(mc);
    const auto ud = static_cast<std::size_t>(dist);
    double* d = data.get();
    const double* kh = kernel_hat.get();
    // In contact most of the quadrant is cavitated (P = 0): the transforms of
    // the input see only the box that holds the pressure, the rest being the
    // zeros apply_padded neither stores nor reads.  The chunks stay those of
    // the whole grid (a vector's arithmetic depends on the count of its
    // chunk), so the result is the one of the whole transform, to the bit.
    const Extent extent = pressurized_extent(p);
    if (extent.rows == 0) {
      std::fill(w, w + un * un, 0.0);
      return;
    }
    // Along X: the rows of P (zero beyond their first extent.columns values),
    // transformed into d; the rows beyond extent.rows are not needed.
    const auto rows_in = [&](int c) {
      by_chunks_of(DctI::kChunk, share(n, parts, c), [&](int first, int count) {
        if (first >= extent.rows) return;
        batches[c].dct.apply_padded(p + first * un, n, extent.columns, d + first * ud, count);
      });
    };
    // Along Y, a few columns kx at a time: their data values (extent.rows of
    // them) transposed into the strip, transform (zero beyond them), product
    // with the kernel spectrum, inverse transform (DCT-I is its own inverse up
    // to the scale), and the first n values transposed back.
    const auto columns = [&](int c) {
      double* strip = batches[c].strip.get();
      by_chunks_of(DctI::kChunk, share(mc, parts, c), [&](int first, int count) {
        transpose(d + first, dist, strip, dist, extent.rows, count);
        batches[c].dct.apply_padded(strip, dist, extent.rows, strip, count);
        for (std::size_t kx = 0; kx < static_cast<std::size_t>(count); ++kx) {
          double* row = strip + kx * ud;
          const double* kernel_row = kh + (first + kx) * umc;
          for (std::size_t ky = 0; ky < umc; ++ky) row[ky] *= kernel_row[ky];
        }
        batches[c].dct.apply(strip, count);
        transpose(strip, dist, d + first, dist, count, n);
      });
    };
    // Along X: the inverse transforms, W out of the first n values.
    const auto rows_out = [&](int c) {
      by_chunks_of(DctI::kChunk, share(n, parts, c), [&](int first, int count) {
        batches[c].dct.apply(d + first * ud, count);
        for (auto j = static_cast<std::size_t>(first); j < static_cast<std::size_t>(first + count);
             ++j)
          std::copy_n(d + j * ud, un, w + j * un);
      });
    };
    in_three_stages(parts, rows_in, columns, rows_out);
  }
};

}  // namespace

FftDeformation::FftDeformation(const Grid2D& grid, FftPlanning planning)
    : DeformationOperator(grid) {
  if (grid.mirrored) {
    impl_ = std::make_unique<MirroredImpl>(kernel(), planning);
  } else {
    impl_ = std::make_unique<FullImpl>(kernel(), planning);
  }
}

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

const char* fft_library_version() { return fftw_version; }

}  // namespace ehlsim
