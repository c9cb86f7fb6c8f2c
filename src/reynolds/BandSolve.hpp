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
  void clear() { std::fill(band_.begin(), band_.end(), 0.0); }

  /// Solves A x = rhs by banded Gaussian elimination (destroys A); rhs becomes x.
  /// The reciprocal of each pivot is taken once, during the elimination: the
  /// back substitution is a chain of dependent steps, and a division in it
  /// costs several times a multiplication.
  void solve(std::vector<double>& rhs) {
    inverse_pivot_.resize(static_cast<std::size_t>(m_));
    for (int i = 0; i < m_; ++i) {
      const double inverse = 1.0 / (*this)(i, i);
      inverse_pivot_[i] = inverse;
      const int last = std::min(m_ - 1, i + b_);
      for (int r = i + 1; r <= last; ++r) {
        const double factor = (*this)(r, i) * inverse;
        if (factor == 0.0) continue;
        for (int c = i; c <= last; ++c) (*this)(r, c) -= factor * (*this)(i, c);
        rhs[r] -= factor * rhs[i];
      }
    }
    for (int i = m_ - 1; i >= 0; --i) {
      double sum = rhs[i];
      const int last = std::min(m_ - 1, i + b_);
      for (int c = i + 1; c <= last; ++c) sum -= (*this)(i, c) * rhs[c];
      rhs[i] = sum * inverse_pivot_[i];
    }
  }

 private:
  int m_, b_;
  std::vector<double> band_;
  std::vector<double> inverse_pivot_;  ///< scratch of solve()
};

}  // namespace ehlsim::reynolds
