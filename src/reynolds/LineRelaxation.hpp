#pragma once
// Line relaxation of the transient EHL Reynolds equation (Venner & Lubrecht,
// MultiLevel Methods in Lubrication, 2000, ch. 11-12), one grid line at a
// time, lines in zebra order (odd, then even; the lines of one colour are
// independent and relaxed in parallel).  The lines run along X, or along X and
// Y in turn: the impact has no preferred direction, and the hard part of its
// solution, the spike ring at the edge of the receding contact, is a curve
// that X lines cross at every angle.  Where they run along the ring, its
// strong radial coupling is left to the point-wise part of the sweep; lines
// along Y cover exactly those parts.
//
// Each point is of one of two kinds, chosen from the frozen coefficients:
//  - Gauss-Seidel (flow-dominated: xi / h^2 large against the elastic-squeeze
//    term): the change is applied at the point itself, at once.
//  - Distributive Jacobi (elastic-dominated: high pressure, thin film): the
//    change delta is applied at the point and -delta/4 at its four neighbours,
//    which turns the first-kind integral equation into a local, diagonally
//    dominant one; these changes are collected and applied after the sweep.
// The line system is the derivative of the operator's own stencil
// (ReynoldsOperator::faces_at and taps_at): the exact derivatives of the flow
// terms, of the density at the point, and of the transport terms through the
// elastic kernel truncated to the band (|i - k| <= 2), for both kinds.
#include <array>
#include <string_view>
#include <vector>

#include "grid/Grid.hpp"
#include "reynolds/ReynoldsOperator.hpp"

namespace ehlsim::reynolds {

/// The relaxation parameters; these defaults are the run's defaults
/// (ImpactConfig holds one of these).  Under-relaxation after Venner &
/// Lubrecht (2000), about 0.4 and 0.2 (model.md).
struct RelaxationSettings {
  /// Switch: a point is relaxed by Gauss-Seidel where
  /// sum of face xi / h^2 >= switch_ratio * (b0/dT) rho K(0,0), else distributively.
  /// Venner & Lubrecht use about 0.3 for their analogous ratio; here it is 10
  /// times that: with the deformation updated once per colour of the zebra
  /// sweep, Gauss-Seidel points where the elastic term is comparable to the
  /// flow term amplify smooth errors (seen as divergence at the dimple
  /// formation on 257^2 with 0.3; docs/model.md).
  double switch_ratio = 3.0;
  /// On a grid whose mesh h is finer than this, the switch ratio is
  /// switch_ratio * switch_reference_mesh / h (each level of a hierarchy by
  /// its own mesh); 0: switch_ratio on every grid (switch_ratio_on).
  double switch_reference_mesh = 0.0;
  double omega_gauss_seidel = 0.4;  ///< under-relaxation of Gauss-Seidel changes
  /// ... at flow-dominated points instead: those whose flow coefficients
  /// exceed kFlowDominatedFactor times the switch's bound, or with no elastic
  /// term (P = 0, rigid bodies).  There the elastic coupling that the line
  /// system leaves out is negligible, and 0.4 only slows a smooth error down
  /// (0.6 per cycle in the approach, 0.16 with 1; docs/performance.md, "Plain
  /// Gauss-Seidel where the flow dominates, and cubic starts").
  double omega_flow_dominated = 1.0;
  double omega_jacobi = 0.3;  ///< under-relaxation of distributive changes
  /// Sweeps alternate between lines along X and lines along Y (X, Y, X, ...
  /// within each relax() call); false: X lines only.  Alternating is what
  /// carries a 513^2 run through the spike phase (docs/model.md).
  bool alternate_directions = true;
  /// The elastic deformation is recomputed before each colour of a zebra
  /// sweep (true), or before the first colour, and before the second only
  /// where the first had more elastically coupled Gauss-Seidel points than
  /// distributive ones (false; else the second colour sees the first colour's
  /// changes through the flow terms, the density and the viscosity, and their
  /// elastic effect from the next sweep on).  false costs about 0.6 times the
  /// deformation evaluations with the same cycles per step (docs/model.md,
  /// section 7).
  bool deformation_each_colour = false;
};

/// The value of the key solver.deformation_updates that selects
/// RelaxationSettings::deformation_each_colour, or not.
inline constexpr std::string_view kUpdatesPerSweep = "sweep";
inline constexpr std::string_view kUpdatesPerColour = "colour";
[[nodiscard]] inline std::string_view deformation_updates_text(bool each_colour) {
  return each_colour ? kUpdatesPerColour : kUpdatesPerSweep;
}

/// A Gauss-Seidel point whose flow coefficients exceed this times the switch's
/// bound (switch_ratio times the elastic term) is flow-dominated and relaxed
/// with omega_flow_dominated.  Measured on the default case (257^2, 513^2): 10
/// slowed the contact (1.91 cycles per step against 1.30), 100 and 1000 did
/// not (docs/performance.md).
inline constexpr double kFlowDominatedFactor = 100.0;

/// The switch ratio a relaxation on mesh size h uses (the settings'
/// switch_ratio, raised on meshes finer than switch_reference_mesh).
[[nodiscard]] double switch_ratio_on(const RelaxationSettings& settings, double h);

/// The grid direction the lines of a sweep run along.
enum class LineDirection { X, Y };

/// Statistics of the last sweep (for diagnostics and tests).
struct SweepStats {
  long gauss_seidel_points = 0;
  long jacobi_points = 0;
};

class LineRelaxation {
 public:
  LineRelaxation(ReynoldsOperator& op, RelaxationSettings settings);

  /// `sweeps` sweeps on N(P) = f; P >= 0 and P = 0 on the boundary are kept.
  void relax(Field& P, const Field& f, int sweeps);
  /// One zebra sweep with lines along `direction` (relax() chooses the
  /// direction per sweep from the settings).
  void sweep(Field& P, const Field& f, LineDirection direction);
  [[nodiscard]] const SweepStats& last_sweep() const { return stats_; }
  /// Scales both under-relaxation factors of the settings by `factor` (1: as set).
  void set_damping(double factor) { damping_ = factor; }
  /// Overrides settings.deformation_each_colour.
  void set_deformation_each_colour(bool each_colour) {
    settings_.deformation_each_colour = each_colour;
  }
  /// Overrides settings.omega_flow_dominated.
  void set_omega_flow_dominated(double omega) { settings_.omega_flow_dominated = omega; }

 private:
  struct LineWork;
  /// The rows of a line system between its first and its last unknown: the
  /// points beyond them at either end are held at P = 0 (cavitated), and
  /// their rows and columns are left out of the system.
  struct RowRange {
    int first, last;
  };
  /// The smallest box i0..i1 x j0..j1 of grid points holding a set of points
  /// (empty: i0 > i1).
  struct PointBox {
    int i0, i1, j0, j1;
  };
  /// What the lines of one colour did: counts of the kinds of points
  /// (LineWork), and the box of the distributive changes.
  struct ColourResult {
    long gauss_seidel, jacobi, coupled_gauss_seidel, distributive;
    PointBox jacobi_box;
  };
  /// Relaxes the lines of one colour of a zebra sweep: the Gauss-Seidel
  /// changes go into P, the distributive ones into jacobi_change_.
  ColourResult relax_colour(Field& P, const Field& f, LineDirection direction, int colour);
  /// Applies the distributive changes of a colour (jacobi_change_, nonzero
  /// within `box` only) to P, and clears them.
  void apply_distributive_changes(Field& P, PointBox box);
  /// Builds and solves the system of one line; leaves the kinds of its points
  /// and their changes in `work` for the rows it returns (beyond them the
  /// points are held, without a change).
  RowRange relax_line(Field& P, const Field& f, int line, LineDirection direction,
                      RowRange candidates, LineWork& work) const;
  /// True where point (i, j) is held at P = 0 by the projection, known
  /// without its faces: P = 0 around it, and a residual that would lower it.
  [[nodiscard]] bool is_held_without_faces(const Field& P, const Field& f, int i, int j) const;
  /// For the Y lines of one colour (first_line, first_line + 2, ...), indexed
  /// by the line: the rows between the first and the last point of the line
  /// that is not is_held_without_faces (beyond them no row needs a look).
  [[nodiscard]] std::vector<RowRange> y_line_candidates(const Field& P, const Field& f,
                                                        int first_line) const;
  /// Lines a thread takes at once in y_line_candidates (their points in one
  /// grid row are 2 * 64 * 8 bytes: whole cache lines).
  static constexpr int kLinesPerBlock = 64;
  /// The residuals of a line's points in `candidates` (the points beyond
  /// them are known to be held), and the face coefficients and kinds of those
  /// not held at P = 0 (those held get fixed_change 0); returns the rows
  /// between the first and the last point not held.
  [[nodiscard]] RowRange line_residuals(const Field& P, const Field& f, int line,
                                        LineDirection direction, RowRange candidates,
                                        LineWork& work) const;
  /// Row r of a line system at point (i, j): its faces, its kind and its residual.
  void set_line_row(const Field& P, const Field& f, int i, int j, LineDirection direction, int r,
                    LineWork& work) const;
  /// The banded Jacobian of the line's residuals with respect to the changes.
  void assemble_line_jacobian(int line, LineDirection direction, RowRange rows,
                              LineWork& work) const;
  struct RowTransport;
  /// One entry of it: row r, the unknown `offset` points along the line.
  [[nodiscard]] double jacobian_entry(int r, int offset, bool jacobi_unknown,
                                      const RowTransport& transport, double self,
                                      const LineWork& work) const;
  /// The elastic kernel of a plain change (K) or of a distributive one (the
  /// change less a quarter at each of the four neighbours) between points
  /// `along` and `across` meshes apart.
  [[nodiscard]] double line_kernel(int along, int across, bool distributed) const {
    const auto& table = distributed ? kernel_distributed_ : kernel_plain_;
    return table[std::abs(along)][std::abs(across)];
  }
  /// Solves the line system with the points held at P = 0 by the projection.
  void solve_projected(const Field& P, int line, LineDirection direction, RowRange rows,
                       LineWork& work) const;

  /// Half-bandwidth of the line systems: the flow terms of a distributive
  /// change reach two points along the line; the elastic kernel is truncated
  /// there too.
  static constexpr int kHalfBand = 2;

  ReynoldsOperator& op_;
  RelaxationSettings settings_;
  /// Kernel offsets the line systems reach: along the line the band plus the
  /// transport taps, across it the taps.
  static constexpr int kMaxAlong = kHalfBand + kTransportTaps - 1;
  static constexpr int kMaxAcross = kTransportTaps - 1;
  using KernelTable = std::array<std::array<double, kMaxAcross + 1>, kMaxAlong + 1>;
  KernelTable kernel_plain_{}, kernel_distributed_{};
  Field jacobi_change_;
  SweepStats stats_;
  double damping_ = 1.0;
};

}  // namespace ehlsim::reynolds
