#pragma once
// The multigrid hierarchy of Reynolds levels that every mode solves on: one
// ReynoldsFasLevel per grid from the finest down to solver.coarsest_points,
// and the generic FAS solver over them.  The global unknown (Delta of the
// impact, H0 of the rolling contact) and the transport coefficients are set
// on every level at once.
#include <memory>
#include <vector>

#include "multigrid/Fas.hpp"
#include "reynolds/ReynoldsFasLevel.hpp"
#include "reynolds/SolverSettings.hpp"

namespace ehlsim {

class ReynoldsHierarchy {
 public:
  /// Levels by standard coarsening of `finest` until the (full) grid has at
  /// most settings.coarsest_points per side; the coarse levels with
  /// settings.coarse_face_mean where it is set.
  ReynoldsHierarchy(const Grid2D& finest, const Lubricant& lubricant,
                    const reynolds::OperatorSettings& op,
                    const reynolds::RelaxationSettings& relaxation,
                    const SolverSettings& settings) {
    Grid2D g = finest;
    std::vector<multigrid::FasLevel*> raw;
    // The coarse levels may take another face mean (solver.coarse_face_mean).
    reynolds::OperatorSettings coarse_op = op;
    coarse_op.face_mean = settings.coarse_face_mean.value_or(op.face_mean);
    while (true) {
      levels_.push_back(std::make_unique<ReynoldsFasLevel>(
          g, lubricant, levels_.empty() ? op : coarse_op, relaxation));
      raw.push_back(levels_.back().get());
      if (g.full().n <= settings.coarsest_points || !g.coarser().coarsenable()) break;
      g = g.coarser();
    }
    multigrid::FasSettings fas;
    fas.pre_sweeps = settings.pre_sweeps;
    fas.post_sweeps = settings.post_sweeps;
    fas.cycle_index = settings.cycle == CycleType::W ? 2 : 1;
    solver_ = std::make_unique<multigrid::FasSolver>(std::move(raw), fas);
  }

  [[nodiscard]] multigrid::FasSolver& solver() { return *solver_; }
  [[nodiscard]] int size() const { return static_cast<int>(levels_.size()); }
  [[nodiscard]] ReynoldsFasLevel& level(int l) { return *levels_[static_cast<std::size_t>(l)]; }
  [[nodiscard]] reynolds::ReynoldsOperator& finest() { return levels_.front()->op(); }
  [[nodiscard]] const reynolds::ReynoldsOperator& finest() const { return levels_.front()->op(); }

  /// The rigid-body separation (Delta, H0) on every level.
  void set_delta(double delta) {
    for (auto& level : levels_) level->op().set_delta(delta);
  }
  /// The squeeze term's time step and BDF coefficient on every level.
  void set_time_step(double dT, double b0) {
    for (auto& level : levels_) level->op().set_time_step(dT, b0);
  }
  /// Scales the under-relaxation of every level's smoother (1: as set).
  void set_damping(double factor) {
    for (auto& level : levels_) level->smoother().set_damping(factor);
  }
  /// Sets when every level's relaxation recomputes the deformation
  /// (reynolds::RelaxationSettings::deformation_each_colour).
  void set_deformation_each_colour(bool each_colour) {
    for (auto& level : levels_) level->smoother().set_deformation_each_colour(each_colour);
  }
  /// Sets every level's under-relaxation at flow-dominated points
  /// (reynolds::RelaxationSettings::omega_flow_dominated).
  void set_omega_flow_dominated(double omega) {
    for (auto& level : levels_) level->smoother().set_omega_flow_dominated(omega);
  }
  /// Deformation evaluations of all levels so far, in finest-grid units:
  /// the machine-independent measure of the work done.
  [[nodiscard]] double work_units() const {
    const double finest_size = static_cast<double>(levels_.front()->grid().size());
    double work = 0.0;
    for (const auto& level : levels_)
      work += static_cast<double>(level->op().deformation_evaluations()) *
              static_cast<double>(level->grid().size()) / finest_size;
    return work;
  }

 private:
  std::vector<std::unique_ptr<ReynoldsFasLevel>> levels_;
  std::unique_ptr<multigrid::FasSolver> solver_;
};

}  // namespace ehlsim
