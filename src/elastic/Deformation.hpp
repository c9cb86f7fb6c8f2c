#pragma once
// Elastic half-space deformation of a grid pressure field:
//   W_ij = sum_kl K(i - k, j - l) P_kl,
// with K the cell kernel (CellKernel.hpp), i.e. the exact deformation of a
// pressure that is constant on the cell of side h around each grid point.  The
// sum runs over all points, boundary points included (they hold P = 0 in the
// impact problem, but the operator does not assume it).
#include <memory>

#include "elastic/CellKernel.hpp"
#include "grid/Grid.hpp"

namespace ehlsim {

/// Interface of the deformation evaluators.  Implementations keep work
/// buffers, so apply() is non-const and one object must not be used by two
/// threads at once (give each thread its own).
class DeformationOperator {
 public:
  virtual ~DeformationOperator() = default;
  DeformationOperator(const DeformationOperator&) = delete;
  DeformationOperator& operator=(const DeformationOperator&) = delete;
  DeformationOperator(DeformationOperator&&) = delete;
  DeformationOperator& operator=(DeformationOperator&&) = delete;

  /// W = K * P on grid().  P must have grid().n points per side; W is
  /// re-created on grid() if its size differs, else overwritten.  P and W must
  /// be different objects (std::invalid_argument otherwise).
  virtual void apply(const Field& P, Field& W) = 0;

  [[nodiscard]] const KernelTable& kernel() const { return kernel_; }
  [[nodiscard]] const Grid2D& grid() const { return grid_; }

 protected:
  explicit DeformationOperator(const Grid2D& grid) : grid_(grid), kernel_(grid.full()) {}
  /// Argument checks shared by the implementations (see apply()).
  void prepare(const Field& P, Field& W) const;

 private:
  Grid2D grid_;
  KernelTable kernel_;
};

/// The O(N^2) direct sum (N = n^2 points): the reference for tests and for
/// small grids.
class DirectDeformation final : public DeformationOperator {
 public:
  explicit DirectDeformation(const Grid2D& grid) : DeformationOperator(grid) {}
  void apply(const Field& P, Field& W) override;
};

/// How much time FFTW spends choosing its algorithms when the plans are made.
///   Measure:  times candidate algorithms: about 0.4 s (n = 257) to 1 s
///             (n = 1025) the first time a size is planned in the process;
///             FFTW keeps the result, so later objects of the same size are
///             set up in 10-200 ms (mostly the kernel table).  apply() was
///             ~25% faster than with Estimate at n = 1025.  The chosen
///             algorithm may differ between runs, so results can differ in
///             the last bits from run to run.
///   Estimate: heuristic choice, instant and reproducible: the same input
///             gives the same bits in every process.  The solver uses it.
enum class FftPlanning { Estimate, Measure };

/// Exact linear convolution by FFT with zero padding (DC-FFT, Liu, Wang & Liu
/// 2000), O(N log N) per apply().  Equals DirectDeformation to rounding.
///
/// The padded period m is the smallest even 2^a 3^b 5^c 7^d >= 2(n - 1) (m = 2(n-1)
/// for n = 2^k + 1).  m = 2(n-1) rather than 2n - 1 is enough because the
/// kernel is even: the offsets +(n-1) and -(n-1), which share a slot of the
/// periodic kernel, need the same value K(n-1).
///
/// The kernel transform is computed once in the constructor; it is real
/// (even kernel) and stored for a quarter of the spectrum only, through a 2-D
/// DCT-I of the kernel table.  The forward transform skips the all-zero padding
/// rows (r2c of the n data rows, then c2c of the columns), the inverse mirrors
/// it, which saves about a quarter of the work of a plain 2-D transform.
///
/// On a mirrored grid (Grid2D::mirrored, the quadrant of a pressure even in X
/// and Y) the convolution is that of the even extensions: a 2-D DCT-I of the
/// quadrant, the product with the same kernel spectrum, and a DCT-I back, on
/// (m/2 + 1)^2 values instead of m^2 (docs/model.md, section 4).  Either way
/// the transforms run in a fixed number of batches, so the result does not
/// depend on the number of threads.
///
/// Plans and buffers are owned by the object (RAII).  FFTW's planner is not
/// thread-safe: constructions and destructions of FftDeformation objects are
/// serialised by an internal mutex, but must not race with FFTW planning done
/// elsewhere in the program.  apply() itself uses only the object's own data.
class FftDeformation final : public DeformationOperator {
 public:
  explicit FftDeformation(const Grid2D& grid, FftPlanning planning = FftPlanning::Estimate);
  ~FftDeformation() override;
  void apply(const Field& P, Field& W) override;

  /// The padded transform size m per side (of the full grid, on a mirrored one).
  [[nodiscard]] int padded_size() const;

  struct Impl;  ///< the transform engine (full or mirrored grid): opaque

 private:
  std::unique_ptr<Impl> impl_;
};

/// FftDeformation (planned with FftPlanning::Estimate: reproducible) when use_fft, else
/// DirectDeformation.
[[nodiscard]] std::unique_ptr<DeformationOperator> make_deformation(const Grid2D& grid,
                                                                    bool use_fft);

/// The FFT library's own version line ("fftw-3.3.10-sse2-avx" with Debian's
/// FFTW): the same binary and input give other bits with another FFTW or
/// CPU (docs/usage.md, "Reproducibility"), so run.json records it.
[[nodiscard]] const char* fft_library_version();

}  // namespace ehlsim
