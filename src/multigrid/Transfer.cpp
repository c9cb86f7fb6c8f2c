#include "multigrid/Transfer.hpp"

#include <cassert>

namespace ehlsim::multigrid {

void inject(const Field& fine, Field& coarse) {
  const int nc = coarse.n();
  assert(fine.n() == 2 * (nc - 1) + 1);
#pragma omp parallel for schedule(static) if (worth_threads(coarse.size()))
  for (int J = 0; J < nc; ++J)
    for (int I = 0; I < nc; ++I) coarse(I, J) = fine(2 * I, 2 * J);
}

void restrict_full_weighting(const Field& fine, Field& coarse) {
  const int nc = coarse.n();
  assert(fine.n() == 2 * (nc - 1) + 1);
  coarse.fill(0.0);
  // On a mirrored grid the interior starts on the axis, where the stencil
  // reads the mirror images across it.
  const int first = coarse.first_interior();
#pragma omp parallel for schedule(static) if (worth_threads(coarse.size()))
  for (int J = first; J < nc - 1; ++J) {
    for (int I = first; I < nc - 1; ++I) {
      const int i = 2 * I, j = 2 * J;
      coarse(I, J) =
          (4.0 * fine(i, j) +
           2.0 * (fine(i - 1, j) + fine(i + 1, j) + fine(i, j - 1) + fine(i, j + 1)) +
           fine(i - 1, j - 1) + fine(i + 1, j - 1) + fine(i - 1, j + 1) + fine(i + 1, j + 1)) /
          16.0;
    }
  }
}

void prolong_bilinear_add(const Field& coarse, Field& fine) {
  const int nf = fine.n();
  assert(nf == 2 * (coarse.n() - 1) + 1);
#pragma omp parallel for schedule(static) if (worth_threads(fine.size()))
  for (int j = 0; j < nf; ++j) {
    const int J = j / 2;
    const bool jodd = (j % 2) != 0;
    for (int i = 0; i < nf; ++i) {
      const int I = i / 2;
      const bool iodd = (i % 2) != 0;
      double value;
      if (!iodd && !jodd) {
        value = coarse(I, J);
      } else if (iodd && !jodd) {
        value = 0.5 * (coarse(I, J) + coarse(I + 1, J));
      } else if (!iodd && jodd) {
        value = 0.5 * (coarse(I, J) + coarse(I, J + 1));
      } else {
        value = 0.25 * (coarse(I, J) + coarse(I + 1, J) + coarse(I, J + 1) + coarse(I + 1, J + 1));
      }
      fine(i, j) += value;
    }
  }
}

namespace {
// Value at the midpoint between coarse points k and k+1 of a 1D sequence of
// length n: 4-point cubic Lagrange (-1, 9, 9, -1)/16 inside, 3-point quadratic
// (3, 6, -1)/8 next to the ends.  A mirrored sequence (get(-1) = get(1)) has
// no end at k = 0.
template <class Get>
double midpoint_cubic(int k, int n, bool mirrored, Get get) {
  if ((k >= 1 || mirrored) && k + 2 <= n - 1)
    return (-get(k - 1) + 9.0 * get(k) + 9.0 * get(k + 1) - get(k + 2)) / 16.0;
  if (k == 0) return (3.0 * get(0) + 6.0 * get(1) - get(2)) / 8.0;
  return (3.0 * get(k + 1) + 6.0 * get(k) - get(k - 1)) / 8.0;
}
}  // namespace

void prolong_cubic(const Field& coarse, Field& fine) {
  const int nc = coarse.n();
  const int nf = fine.n();
  assert(nf == 2 * (nc - 1) + 1);
  const bool mirrored = coarse.first_interior() == 0;
  // Rows of the coarse grid first (even fine rows), then the odd rows between them.
  for (int J = 0; J < nc; ++J) {
    for (int I = 0; I < nc; ++I) fine(2 * I, 2 * J) = coarse(I, J);
    for (int I = 0; I < nc - 1; ++I)
      fine(2 * I + 1, 2 * J) = midpoint_cubic(I, nc, mirrored, [&](int k) { return coarse(k, J); });
  }
  for (int J = 0; J < nc - 1; ++J)
    for (int i = 0; i < nf; ++i)
      fine(i, 2 * J + 1) = midpoint_cubic(J, nc, mirrored, [&](int k) { return fine(i, 2 * k); });
}

}  // namespace ehlsim::multigrid
