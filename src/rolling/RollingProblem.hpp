#pragma once
// The steady rolling point contact (model.md, "Steady rolling point
// contact") on the impact's solver: the same Reynolds operator with the wedge
// term in place of the squeeze term, the same line relaxation and FAS
// multigrid.  The rigid-body separation H0 is the global unknown that the
// force balance Int P dX dY = 2 pi / 3 fixes; it is updated after every
// cycle.  The solution starts from the Hertz pressure on the coarsest grid and
// is carried up by full multigrid.
#include <functional>
#include <memory>
#include <numbers>
#include <stdexcept>
#include <string>
#include <vector>

#include "grid/Grid.hpp"
#include "rolling/RollingConfig.hpp"

namespace ehlsim {

/// The state after one cycle on one level of the full multigrid.
struct RollingCycle {
  int points = 0;            ///< points per side of the level
  int cycle = 0;             ///< cycle on that level, from 1, over all its attempts
  int attempt = 0;           ///< attempt on that level: 0, then the retries
  double damping = 1.0;      ///< the attempt's under-relaxation factor
  double residual = 0.0;     ///< pressure-scaled residual norm
  double force_error = 0.0;  ///< (h^2 sum P - 2 pi / 3) / (2 pi / 3)
  double Hc = 0.0;           ///< central film H(0, 0)
  double H0 = 0.0;
  double work = 0.0;         ///< deformation evaluations so far, in finest-grid units
  bool each_colour = false;  ///< deformation updated before each colour (else once per sweep)
};

struct RollingResult {
  Grid2D grid;
  Field P, H;
  double Hc = 0.0;  ///< H at X = Y = 0
  /// The Nijenbanning-Venner-Moes central film of the case (Moes units),
  /// and Hc's relative deviation from it.
  double Hc_moes_nvm = 0.0, nvm_deviation = 0.0;
  double Hm = 0.0, X_Hm = 0.0, Y_Hm = 0.0;           ///< minimum film and its position
  double P_max = 0.0, X_P_max = 0.0, Y_P_max = 0.0;  ///< maximum pressure and its position
  double H0 = 0.0;
  double residual = 0.0, force_error = 0.0;
  int cycles = 0;            ///< on the finest grid, of the run that converged
  double work = 0.0;         ///< deformation evaluations of every run, in finest-grid units
  bool each_colour = false;  ///< the deformation update of the run that converged
  /// Finest-grid cycles of a first run that ran out of them with the other
  /// update (RollingConfig::fallback_update); 0 when the first run converged.
  int fallback_after = 0;
  double edge_load = 0.0;  ///< edge_load_share of P
  /// What the user should know about the result (the load reaching the
  /// domain's inlet and side edges), one line each.
  std::vector<std::string> warnings;
  std::vector<RollingCycle> history;
};

/// A run that did not converge: what() names the level, the cycles and the residual.
class RollingFailure : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class RollingProblem {
 public:
  explicit RollingProblem(const RollingConfig& config);
  ~RollingProblem();
  RollingProblem(const RollingProblem&) = delete;
  RollingProblem& operator=(const RollingProblem&) = delete;

  using CycleMonitor = std::function<void(const RollingCycle&)>;
  /// Told, in one line, why the first run failed and that the solve starts
  /// again with the other deformation update (RollingConfig::fallback_update).
  using FallbackMonitor = std::function<void(const std::string& line)>;
  /// Solves to solver.tolerance; throws RollingFailure when it cannot.  An
  /// elastic contact that runs out of cycles with one deformation update is
  /// solved again from its start with the other (RollingConfig::fallback_update).
  [[nodiscard]] RollingResult run(const CycleMonitor& monitor = {},
                                  const FallbackMonitor& on_fallback = {});
  /// The grid of the case's domain and grid.points.
  [[nodiscard]] static Grid2D grid_of(const RollingConfig& config);

 private:
  [[nodiscard]] RollingResult solve(const CycleMonitor& monitor);
  /// solve() again from the start with the other deformation update, after
  /// a first run that ran out of cycles with `why`.
  [[nodiscard]] RollingResult solve_with_other_update(const std::string& why,
                                                      const CycleMonitor& monitor,
                                                      const FallbackMonitor& on_fallback);
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// The widest mesh on which the dry Hertz ellipse of an elastic contact is
/// resolved: its smaller semi-axis (one mesh; RollingProblem.cpp says why).
/// The full multigrid starts on the coarsest grid this fine; a finest grid
/// coarser than this is bad input.
[[nodiscard]] double widest_resolving_mesh(const RollingConfig& config);

/// The force balance of the Hertz units: Int P dX dY = 2 pi / 3.
inline constexpr double kRollingLoad = 2.0 * std::numbers::pi / 3.0;

/// The share of the load sum P that the edge band (grid/EdgeBand.hpp) along
/// the inlet edge (X = x_min) and the side edges (Y = y_min, y_max) carries:
/// 0.28 for a uniform P (all but 0.9 x 0.8 of the domain).  A pressure that
/// reaches the edges starves the contact of the load that the boundary
/// condition P = 0 takes away.  The outlet edge is left out: past the
/// cavitation boundary the pressure is zero anyway, and on the default domain
/// (x_max = 1.5) its band would hold the edge of the Hertz contact.
[[nodiscard]] double edge_load_share(const Grid2D& grid, const Field& P);

}  // namespace ehlsim
