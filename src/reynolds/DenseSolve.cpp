#include "reynolds/DenseSolve.hpp"

#include <stdexcept>

extern "C" void dgesv_(const int* n, const int* nrhs, double* a, const int* lda, int* ipiv,
                       double* b, const int* ldb, int* info);

namespace ehlsim::reynolds {

bool solve_dense(std::vector<double>& A, std::vector<double>& b, int m) {
  if (A.size() != static_cast<std::size_t>(m) * m || b.size() < static_cast<std::size_t>(m))
    throw std::invalid_argument("solve_dense: the sizes of A and b do not match m");
  if (m == 0) return true;
  std::vector<int> pivots(static_cast<std::size_t>(m));
  const int one = 1;
  int info = 0;
  dgesv_(&m, &one, A.data(), &m, pivots.data(), b.data(), &m, &info);
  return info == 0;
}

}  // namespace ehlsim::reynolds
