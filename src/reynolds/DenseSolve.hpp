#pragma once
// Dense linear systems, by LAPACK's dgesv (LU with partial pivoting; Debian's
// reference LAPACK: one thread, the same bits in every run).
#include <vector>

namespace ehlsim::reynolds {

/// Solves A x = b for the m x m matrix A, stored by columns (A(r, c) at
/// c * m + r) and overwritten by its LU factors; b becomes x.  False when A
/// is singular.
[[nodiscard]] bool solve_dense(std::vector<double>& A, std::vector<double>& b, int m);

}  // namespace ehlsim::reynolds
