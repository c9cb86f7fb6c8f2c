#pragma once
// The multigrid settings every mode reads from its [solver] section (declared
// once for all modes: config/ParameterSet.hpp, add_solver_parameters).
#include <optional>

#include "reynolds/FaceMean.hpp"
#include "reynolds/LineRelaxation.hpp"

namespace ehlsim {

enum class CycleType { V, W };
enum class DeformationMethod { Fft, Direct };

/// The defaults: V(3,2) cycles down to 17^2 (docs/model.md, section 6; V(2,1),
/// V(2,2), V(3,1) cost the same within the noise on 129^2, V(1,1) kept steps
/// above the tolerance: docs/performance.md) and the stopping rule of
/// section 8 (the tolerance and its error against runs converged to 1e-8:
/// docs/validation.md, "The quadrant, and the physics did not move").
struct SolverSettings {
  CycleType cycle = CycleType::V;
  double tolerance = 1e-5;  ///< on the pressure-scaled residual of the finest grid
  int max_cycles = 20;
  int pre_sweeps = 3;
  int post_sweeps = 2;
  int coarsest_points = 17;  ///< the coarsest multigrid level has this many points per side
  DeformationMethod deformation = DeformationMethod::Fft;
  reynolds::RelaxationSettings relaxation;  ///< switch and under-relaxation (defaults there)
  FaceMean face_mean = FaceMean::Arithmetic;
  /// The face mean of the coarse multigrid levels; none: face_mean.  The
  /// coarse operators only carry corrections (FAS), so this changes the
  /// iteration, not the solution it converges to.
  std::optional<FaceMean> coarse_face_mean;
  /// Refuse a run whose memory estimate exceeds this [MB]; 0: the machine's
  /// available memory (io/MemoryGuard.hpp).
  double memory_limit_mb = 0.0;
  /// After each cycle that leaves the finest grid above the tolerance: one
  /// Newton step on windows of this many meshes to each side of the largest
  /// pressure-scaled residuals (reynolds/LocalNewton.hpp); 0: none.  6: on
  /// 513^2 the impact's pocket collapse took 163 instead of 398 work units
  /// per step and no step was kept above the tolerance; the rolling contact
  /// at L = 20 on 513^2 took 33 instead of 87 cycles (M = 20, tolerance 1e-4;
  /// docs/validation.md).
  int local_newton_half_width = 6;
  /// The most windows of a local Newton step, each centred on one of the
  /// largest residuals, no two overlapping, all solved at the same iterate;
  /// 0: one per 32 points of the side of the grid solved on
  /// (reynolds::window_search).
  int local_newton_windows = 0;
};

}  // namespace ehlsim
