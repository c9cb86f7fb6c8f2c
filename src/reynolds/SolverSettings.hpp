#pragma once
// The multigrid settings every mode reads from its [solver] section (declared
// once for all modes: io/ParameterSet.hpp, add_solver_parameters).
#include "reynolds/FaceMean.hpp"
#include "reynolds/LineRelaxation.hpp"

namespace ehlsim {

enum class CycleType { V, W };
enum class DeformationMethod { Fft, Direct };

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
  /// Refuse a run whose memory estimate exceeds this [MB]; 0: the machine's
  /// available memory (io/MemoryGuard.hpp).
  double memory_limit_mb = 0.0;
};

}  // namespace ehlsim
