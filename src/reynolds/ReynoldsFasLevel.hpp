#pragma once
// Adapter that presents one grid's Reynolds operator and line relaxation to the
// generic FAS solver: the only place where the physics meets the multigrid.
#include <algorithm>

#include "multigrid/Fas.hpp"
#include "reynolds/LineRelaxation.hpp"
#include "reynolds/ReynoldsOperator.hpp"

namespace ehlsim {

class ReynoldsFasLevel final : public multigrid::FasLevel {
 public:
  ReynoldsFasLevel(const Grid2D& grid, const Lubricant& lubricant,
                   const reynolds::OperatorSettings& op_settings,
                   const reynolds::RelaxationSettings& relax_settings)
      : op_(grid, lubricant, op_settings), smoother_(op_, relax_settings), mask_(grid) {}

  reynolds::ReynoldsOperator& op() { return op_; }
  [[nodiscard]] const reynolds::ReynoldsOperator& op() const { return op_; }
  reynolds::LineRelaxation& smoother() { return smoother_; }

  [[nodiscard]] const Grid2D& grid() const override { return op_.grid(); }
  void apply(const Field& u, Field& Nu) override { op_.apply(u, Nu); }
  void residual(const Field& u, const Field& f, Field& r) override {
    op_.apply(u, r);
    for_each_element(
        r.size(), [&](std::size_t k) { r[k] = reynolds::constrained_residual(u[k], f[k] - r[k]); });
    zero_boundary(r);
  }
  /// The coarse-grid correction is applied only inside the pressurized region
  /// (the point and its four neighbours have P > 0): the coarse grid cannot
  /// resolve the free (cavitation) boundary, and its corrections there would
  /// undo what relaxation found, down to a cycle that stalls.
  void correct(Field& u, const Field& correction) override {
    // The mask is taken before any point changes: it is a property of u as
    // the coarse grid saw it.
    const int n = u.n();
    const int first = u.first_interior();
    const bool threaded = worth_threads(u.size());
#pragma omp parallel for schedule(static) if (threaded)
    for (int j = first; j < n - 1; ++j)
      for (int i = first; i < n - 1; ++i)
        mask_(i, j) = reynolds::is_pressurized(u, i, j) ? 1.0 : 0.0;
#pragma omp parallel for schedule(static) if (threaded)
    for (int j = first; j < n - 1; ++j)
      for (int i = first; i < n - 1; ++i)
        if (mask_(i, j) != 0.0) u(i, j) = std::max(0.0, u(i, j) + correction(i, j));
  }
  /// Root mean square of r / |dN/dP| over the interior: the pressure change
  /// that would remove the residual, so that points where the flow terms are
  /// huge (thick film, far from the contact) do not dominate the measure.
  double norm(const Field& r) override { return op_.pressure_scaled_norm(r); }
  void relax(Field& u, const Field& f, int sweeps) override { smoother_.relax(u, f, sweeps); }
  void project(Field& u) override {
    for_each_element(u.size(), [&](std::size_t k) { u[k] = std::max(u[k], 0.0); });
    zero_boundary(u);
  }

 private:
  /// P = 0 on the boundary: the far edges, and on a full grid the near ones
  /// (on a mirrored grid those are the symmetry axes, which are unknowns).
  static void zero_boundary(Field& u) {
    const int n = u.n();
    for (int k = 0; k < n; ++k) u(k, n - 1) = u(n - 1, k) = 0.0;
    if (u.first_interior() == 0) return;
    for (int k = 0; k < n; ++k) u(k, 0) = u(0, k) = 0.0;
  }

  reynolds::ReynoldsOperator op_;
  reynolds::LineRelaxation smoother_;
  Field mask_;  ///< 1 where the coarse-grid correction applies
};

}  // namespace ehlsim
