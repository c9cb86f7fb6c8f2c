#pragma once
// The lubricant model choices (model.md, "Lubricant models").  Kept in their own
// header so that the run configuration can name them without pulling in the
// pointwise rheology functions.

namespace ehlsim {

enum class ViscosityModel { Barus, Roelands };
enum class DensityModel { Incompressible, DowsonHigginson };

}  // namespace ehlsim
