#pragma once
// A generic Full Approximation Scheme (FAS) multigrid solver for a nonlinear,
// constrained system N(u) = f on a hierarchy of uniform grids (Brandt 1977;
// Venner & Lubrecht 2000, ch. 3).  It knows nothing of the physics: each level
// supplies its operator, smoother and constraint through FasLevel.
#include <memory>
#include <vector>

#include "grid/Grid.hpp"

namespace ehlsim::multigrid {

/// The per-level interface the FAS solver needs.
class FasLevel {
 public:
  virtual ~FasLevel() = default;
  [[nodiscard]] virtual const Grid2D& grid() const = 0;
  /// N(u) at every interior point (zero on the boundary).
  virtual void apply(const Field& u, Field& Nu) = 0;
  /// r = f - N(u) where the equation holds; zero where the constraint is active
  /// (so that restricted residuals carry no information from those points).
  virtual void residual(const Field& u, const Field& f, Field& r) = 0;
  /// `sweeps` relaxation sweeps on N(u) = f.
  virtual void relax(Field& u, const Field& f, int sweeps) = 0;
  /// Enforce the constraint (e.g. u >= 0) after a coarse-grid correction.
  virtual void project(Field& u) = 0;
  /// Adds an interpolated coarse-grid correction to u.  Default: u += c, then
  /// project().
  virtual void correct(Field& u, const Field& correction);
  /// The norm in which convergence is judged, of a residual from residual().
  /// Default: root mean square over the interior points.
  virtual double norm(const Field& r);
};

struct FasSettings {
  int pre_sweeps = 2;
  int post_sweeps = 1;
  /// Relaxations on the coarsest grid per visit (docs/model.md, section 6):
  /// cheap there, a sweep of 17^2 (289 points) being 1/230 of one of 257^2.
  int coarsest_sweeps = 10;
  int cycle_index = 1;  ///< 1: V cycle, 2: W cycle
  int fmg_cycles = 1;   ///< cycles per level in the full multigrid start
  /// A coarse-grid correction that leaves the level's residual norm more than
  /// this many times its value before the correction is undone (the cycle goes
  /// on with the post-smoothing).  0: every correction is applied.  A good
  /// correction reduces the norm (by 5-7 times in the impact runs) even before
  /// post-smoothing; one that raises it tenfold comes from a coarse problem
  /// that cannot represent the solution (a spike a few meshes wide) and can
  /// blow the iteration up.
  double correction_safeguard = 0.0;
};

class FasSolver {
 public:
  /// levels[0] is the finest; each next one the standard coarsening of the previous.
  FasSolver(std::vector<FasLevel*> levels, FasSettings settings);

  [[nodiscard]] int num_levels() const { return static_cast<int>(levels_.size()); }
  Field& solution(int level = 0) { return u_[level]; }
  Field& rhs(int level = 0) { return f_[level]; }

  /// One cycle (V or W) on the finest grid, or on the sub-hierarchy whose
  /// finest grid is `level` (the steps of a full multigrid driven from
  /// outside, e.g. with a global unknown updated between the cycles).
  void cycle(int level = 0) { cycle_on(level); }
  /// Carries the solution of level + 1 up to `level` (cubic interpolation,
  /// then the constraint): the start of a full multigrid stage.
  void interpolate_solution(int level);
  /// Full multigrid: solve N(u) = f on the coarsest grid, carry the solution up
  /// with cubic interpolation, and on each finer grid perform fmg_cycles cycles.
  /// The right-hand sides of the coarse levels are restricted from the finest.
  void full_multigrid();
  /// Residual of the finest grid (or of `level`, with its own right-hand
  /// side) in that level's norm().
  double residual_norm(int level = 0);
  /// The right-hand sides of the coarse levels restricted from the finest:
  /// what a full multigrid solves on each level before carrying it up.
  void restrict_rhs_to_coarse_levels();
  /// Coarse-grid corrections undone by the safeguard, on any level, since construction.
  [[nodiscard]] long rejected_corrections() const { return rejected_corrections_; }
  void set_correction_safeguard(double factor) { settings_.correction_safeguard = factor; }

 private:
  void cycle_on(int level);

  std::vector<FasLevel*> levels_;
  FasSettings settings_;
  std::vector<Field> u_, f_, r_, u_coarse_old_, scratch_;
  std::vector<Field> saved_;  ///< u before the correction, for the safeguard
  long rejected_corrections_ = 0;
};

}  // namespace ehlsim::multigrid
