#pragma once
// The choice of the flow coefficient on a cell face, shared by the operator
// and the run configuration.

namespace ehlsim {

/// Mean of the flow coefficient xi of two neighbouring points on their face.
enum class FaceMean { Arithmetic, Harmonic, Logarithmic };

}  // namespace ehlsim
