#pragma once
// In-place solution of a banded linear system without pivoting.  Meant for the
// small, diagonally dominant line systems of the relaxation, where pivoting is
// not needed and the band is narrow.
#include <algorithm>
#include <cstddef>
#include <vector>

namespace ehlsim::reynolds {

/// A square banded matrix of size m with half-bandwidth b, stored by rows:
/// entry (i, k) for |i - k| <= b at band[i * (2b + 1) + (k - i + b)].
class BandMatrix {
 public:
  BandMatrix(int size, int half_band)
      : m_(size), b_(half_band), band_(static_cast<std::size_t>(size) * (2 * half_band + 1), 0.0) {}
  [[nodiscard]] int size() const { return m_; }
  [[nodiscard]] int half_band() const { return b_; }
  double& operator()(int i, int k) {
    return band_[static_cast<std::size_t>(i) * (2 * b_ + 1) + (k - i + b_)];
  }
  /// Zeroes rows first..last.
  void clear_rows(int first, int last) { std::fill(row_begin(first), row_begin(last + 1), 0.0); }
  /// Copies rows first..last of `other` (of the same shape).
  void copy_rows(const BandMatrix& other, int first, int last) {
    std::copy(other.row_begin(first), other.row_begin(last + 1), row_begin(first));
  }

  /// Solves A x = rhs by banded Gaussian elimination (destroys A); rhs becomes x.
  void solve(std::vector<double>& rhs) { solve(rhs, 0, m_ - 1); }
  /// The same for the block of rows and columns first..last alone (the rest of
  /// A and rhs is not touched).  The reciprocal of each pivot is taken once,
  /// during the elimination: the back substitution is a chain of dependent
  /// steps, and a division in it costs several times a multiplication.
  void solve(std::vector<double>& rhs, int first, int last) {
    inverse_pivot_.resize(static_cast<std::size_t>(m_));
    for (int i = first; i <= last; ++i) {
      const double inverse = 1.0 / (*this)(i, i);
      inverse_pivot_[i] = inverse;
      const int band_end = std::min(last, i + b_);
      for (int r = i + 1; r <= band_end; ++r) {
        const double factor = (*this)(r, i) * inverse;
        if (factor == 0.0) continue;
        for (int c = i; c <= band_end; ++c) (*this)(r, c) -= factor * (*this)(i, c);
        rhs[r] -= factor * rhs[i];
      }
    }
    for (int i = last; i >= first; --i) {
      double sum = rhs[i];
      const int band_end = std::min(last, i + b_);
      for (int c = i + 1; c <= band_end; ++c) sum -= (*this)(i, c) * rhs[c];
      rhs[i] = sum * inverse_pivot_[i];
    }
  }

 private:
  [[nodiscard]] std::vector<double>::iterator row_begin(int i) {
    return band_.begin() + static_cast<std::ptrdiff_t>(i) * (2 * b_ + 1);
  }
  [[nodiscard]] std::vector<double>::const_iterator row_begin(int i) const {
    return band_.begin() + static_cast<std::ptrdiff_t>(i) * (2 * b_ + 1);
  }

  int m_, b_;
  std::vector<double> band_;
  std::vector<double> inverse_pivot_;  ///< scratch of solve()
};

}  // namespace ehlsim::reynolds
