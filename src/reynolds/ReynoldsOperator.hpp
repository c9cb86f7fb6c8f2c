#pragma once
// The discrete Reynolds operator on one grid (model.md), second order in
// space, for the impact and the rolling contact alike:
//
//   N(P)_ij = (1/h^2) [ xi_e (P_e - P) - xi_w (P - P_w) + xi_n (P_n - P) - xi_s (P - P_s) ]
//             - sum_t c_t (rho H)_{i-t,j}
//
// with xi = rho H^3 / (eta lambda_bar) at the points and means on the faces,
// H = Delta + X^2/2 + D Y^2/2 + waviness + W(P) (W: elastic deformation, D the
// curvature ratio of an elliptic contact, 1 for a ball), and the transport
// taps c_t (TransportTaps) of the squeeze term b0/dT d(rho H) (the impact; b0
// the BDF coefficient of the new time level) and of the wedge term
// d(rho H)/dX (the rolling contact, upwind).  The known terms of earlier time
// levels belong to the right-hand side f, so that one time step, or the
// steady state, is the nonlinear problem N(P) = f, P >= 0, P = 0 on the
// boundary.
//
// This stencil is the one discretisation: the residual evaluates it
// (apply_at) and the line relaxation differentiates it (faces_at, taps_at).
// The operator knows nothing of the solver; it exposes its frozen
// coefficients (H, rho, xi) for the relaxation.
#include <algorithm>
#include <array>
#include <cmath>
#include <memory>
#include <numbers>

#include "elastic/Deformation.hpp"
#include "grid/Grid.hpp"
#include "reynolds/FaceMean.hpp"
#include "rheology/Lubricant.hpp"

namespace ehlsim::reynolds {

/// Flow coefficient on the face between two points with coefficients a and b.
/// FaceMean::Arithmetic is the classic choice (Venner & Lubrecht 2000);
/// FaceMean::Harmonic is the conductance of the two half cells in series, the
/// finite-volume choice for coefficients that jump by orders of magnitude from
/// one point to the next (exp(alpha_bar P) with alpha_bar P ~ 30 at the rim of
/// an entrapped pocket); it underestimates the flux there by many orders.
/// FaceMean::Logarithmic, (a - b) / ln(a / b), is the exact face flux of the
/// Kirchhoff transform for xi = c exp(-alpha_bar P) (Barus, constant H):
/// q = -(1/h) Int xi dP.  All three are second order where xi is smooth.
using ehlsim::FaceMean;

/// Below this |a/b - 1| the logarithmic mean is taken as the arithmetic one.
inline constexpr double kLogMeanSeriesBound = 1e-4;

inline double face_coefficient(double a, double b, FaceMean mean) {
  if (mean == FaceMean::Arithmetic) return 0.5 * (a + b);
  if (mean == FaceMean::Logarithmic) {
    if (a <= 0.0 || b <= 0.0) return 0.0;
    const double ratio = a / b;
    // Near ratio 1 the quotient loses digits; there the log mean is the
    // arithmetic mean to a relative (ratio - 1)^2 / 12 < 1e-9.
    if (std::abs(ratio - 1.0) < kLogMeanSeriesBound) return 0.5 * (a + b);
    return (a - b) / std::log(ratio);
  }
  const double sum = a + b;
  return sum > 0.0 ? 2.0 * a * b / sum : 0.0;
}

/// The partial derivatives of face_coefficient(a, b, mean) with respect to a
/// and b: how a face's flow coefficient follows the point values of xi (the
/// Newton terms of a coefficient that depends on the pressure).
struct FaceSlopes {
  double a, b;
};
inline FaceSlopes face_coefficient_slopes(double a, double b, FaceMean mean) {
  if (mean == FaceMean::Arithmetic) return {0.5, 0.5};
  if (mean == FaceMean::Logarithmic) {
    if (a <= 0.0 || b <= 0.0) return {0.0, 0.0};
    const double ratio = a / b;
    if (std::abs(ratio - 1.0) < kLogMeanSeriesBound) return {0.5, 0.5};
    // F = (a - b) / L with L = ln(a / b): dF/da = (1 - F/a) / L, dF/db = (F/b - 1) / L.
    const double log_ratio = std::log(ratio);
    const double F = (a - b) / log_ratio;
    return {(1.0 - F / a) / log_ratio, (F / b - 1.0) / log_ratio};
  }
  const double sum = a + b;
  if (sum <= 0.0) return {0.0, 0.0};
  // F = 2ab / (a + b).
  return {2.0 * b * b / (sum * sum), 2.0 * a * a / (sum * sum)};
}

/// Sinusoidal surface waviness added to the gap: A cos(2 pi (X cos th + Y sin th) / wavelength).
struct Waviness {
  double amplitude = 0.0;
  double wavelength = 1.0;
  double angle_deg = 0.0;
  /// The height of the waviness at (x, y).
  [[nodiscard]] double height(double x, double y) const {
    // No wave: also for a wavelength whose wave number overflows (1e-308),
    // where 0 cos(inf) would be a NaN gap.
    if (amplitude == 0.0) return 0.0;
    const double angle = angle_deg * std::numbers::pi / 180.0;
    const double kx = 2.0 * std::numbers::pi * std::cos(angle) / wavelength;
    const double ky = 2.0 * std::numbers::pi * std::sin(angle) / wavelength;
    return amplitude * std::cos(kx * x + ky * y);
  }
};

struct OperatorSettings {
  double lambda_bar = 1.0;
  /// Coefficient of the wedge term -d(rho H)/dX: 1 for a contact whose
  /// surfaces carry the lubricant along +X (the rolling contact), 0 for the
  /// impact.
  double wedge = 0.0;
  /// D = Rx / Ry: the undeformed gap is X^2/2 + D Y^2/2 (1: a ball).
  double curvature_ratio = 1.0;
  bool elastic = true;  ///< false: rigid bodies, W = 0
  bool use_fft = true;  ///< FFT convolution (fast) or direct summation (reference)
  Waviness waviness;
  FaceMean face_mean = FaceMean::Arithmetic;
};

/// True where the interior point (i, j) and its four neighbours all carry
/// pressure: inside the pressurized region, away from the cavitation boundary.
inline bool is_pressurized(const Field& P, int i, int j) {
  return P(i, j) > 0.0 && P(i - 1, j) > 0.0 && P(i + 1, j) > 0.0 && P(i, j - 1) > 0.0 &&
         P(i, j + 1) > 0.0;
}

/// True where the interior point (i, j) and its four neighbours carry no
/// pressure: there the flow terms of N vanish (exactly +0, as the stencil
/// gives them) and the faces need not be formed.  Most of the domain in the
/// rebound: 79 % of the 1025^2 points at T = 3.5, 92 % at T = 3.99.
inline bool is_cavitated_around(const Field& P, int i, int j) {
  return P(i, j) == 0.0 && P(i - 1, j) == 0.0 && P(i + 1, j) == 0.0 && P(i, j - 1) == 0.0 &&
         P(i, j + 1) == 0.0;
}

/// The residual r = f - N(P) of a point as the constrained problem (P >= 0)
/// counts it: where P = 0 the equation holds as an inequality, and only a
/// residual that would raise the pressure (r < 0, since dN/dP < 0) is one.
inline double constrained_residual(double P, double r) { return P > 0.0 ? r : std::min(r, 0.0); }

/// Points upstream (-X) whose rho H enter the transport term of a point.
inline constexpr int kTransportTaps = 3;

/// The transport part of the stencil at one point: N includes
/// -weight[t] (rho H)(i - t, j) for t = 0, 1, 2.
struct TransportTaps {
  std::array<double, kTransportTaps> weight{};
};

class ReynoldsOperator {
 public:
  ReynoldsOperator(const Grid2D& grid, const Lubricant& lubricant,
                   const OperatorSettings& settings);

  [[nodiscard]] const Grid2D& grid() const { return grid_; }
  [[nodiscard]] const Lubricant& lubricant() const { return lubricant_; }
  [[nodiscard]] bool elastic() const { return settings_.elastic; }
  [[nodiscard]] FaceMean face_mean() const { return settings_.face_mean; }
  /// Face coefficient between points (i, j) and (i + di, j + dj).
  [[nodiscard]] double face(int i, int j, int di, int dj) const {
    return face_coefficient(xi_(i, j), xi_(i + di, j + dj), settings_.face_mean);
  }

  /// BDF coefficient b0 of the new level and the time step (d/dT ~ (b0 u^{n+1} + ...)/dT).
  void set_time_step(double dT, double b0) {
    dT_ = dT;
    b0_ = b0;
  }
  [[nodiscard]] double squeeze_coefficient() const { return b0_ / dT_; }
  /// The transport taps of a point in column i: the squeeze term at the point
  /// itself, the wedge term by the second-order upwind difference
  /// (3 u_i - 4 u_{i-1} + u_{i-2}) / (2h), first order next to the inflow
  /// boundary, where u_{i-2} is outside the grid.
  [[nodiscard]] TransportTaps taps_at(int i) const {
    TransportTaps taps{{b0_ / dT_, 0.0, 0.0}};
    if (settings_.wedge == 0.0) return taps;
    const double c = settings_.wedge / grid_.h();
    if (i >= 2) {
      taps.weight[0] += 1.5 * c;
      taps.weight[1] = -2.0 * c;
      taps.weight[2] = 0.5 * c;
    } else {
      taps.weight[0] += c;
      taps.weight[1] = -c;
    }
    return taps;
  }
  /// d(transport term) / d(deformation) at the point itself:
  /// sum_t weight[t] rho_{i-t,j} K(t, 0), the elastic part of the diagonal.
  [[nodiscard]] double elastic_diagonal(int i, int j) const;
  void set_delta(double Delta) { delta_ = Delta; }
  [[nodiscard]] double delta() const { return delta_; }

  /// Recompute deformation, film thickness, density and xi for pressure P.
  void update_coefficients(const Field& P);
  /// The same, but the deformation is kept from the last update (density,
  /// viscosity, film and xi follow P): for a relaxation that brings the
  /// deformation up to date less often than the flow terms.
  void update_coefficients_keeping_deformation(const Field& P);
  /// Evaluations of the deformation integral so far (the costly part of an
  /// update): the measure of the work done on this grid.
  [[nodiscard]] long deformation_evaluations() const { return deformation_evaluations_; }
  /// N(P) at interior points (zero on the boundary); updates the coefficients.
  void apply(const Field& P, Field& N);
  /// The four face coefficients of interior point (i, j), by compass direction
  /// (west: i - 1, east: i + 1, south: j - 1, north: j + 1).
  struct Faces {
    double west, east, south, north;
  };
  [[nodiscard]] Faces faces_at(int i, int j) const {
    return {face(i, j, -1, 0), face(i, j, 1, 0), face(i, j, 0, -1), face(i, j, 0, 1)};
  }
  /// N(P)_ij at one interior point from the current (frozen) coefficients.
  [[nodiscard]] double apply_at(const Field& P, int i, int j) const {
    if (is_cavitated_around(P, i, j)) return cavitated_apply_at(i, j);
    return apply_at(P, i, j, faces_at(i, j));
  }
  /// N(P)_ij where is_cavitated_around(P, i, j): the transport term alone,
  /// to the bit what apply_at gives with the faces.
  [[nodiscard]] double cavitated_apply_at(int i, int j) const {
    return 0.0 - transport_at(i, j, taps_at(i));
  }
  /// The same, with the point's faces_at() already at hand.
  [[nodiscard]] double apply_at(const Field& P, int i, int j, const Faces& faces) const;
  /// The transport term sum_t weight[t] (rho H)_{i-t,j} of a point.
  [[nodiscard]] double transport_at(int i, int j, const TransportTaps& taps) const {
    double sum = taps.weight[0] * rho_(i, j) * H_(i, j);
    for (int t = 1; t < kTransportTaps; ++t)
      if (taps.weight[t] != 0.0) sum += taps.weight[t] * rho_(i - t, j) * H_(i - t, j);
    return sum;
  }

  // Coefficients of the last update_coefficients().
  [[nodiscard]] const Field& film() const { return H_; }
  /// The elastic deformation W(P) in the film (zero for rigid bodies).
  [[nodiscard]] const Field& deformation() const { return W_; }
  [[nodiscard]] const Field& density() const { return rho_; }
  [[nodiscard]] const Field& xi() const { return xi_; }
  /// d rho / d P at the points (for the Newton diagonal of compressible fluids).
  [[nodiscard]] const Field& density_derivative() const { return drho_; }
  /// Deformation kernel coefficient K(di, dj) of this grid (0 when rigid).
  [[nodiscard]] double kernel(int di, int dj) const;
  /// dH(a, b) / dP(k, l): the film's response at point (a, b) to the pressure
  /// of the unknown (k, l), which on a mirrored grid stands for its images
  /// (+-k, +-l) too (0 when rigid).
  [[nodiscard]] double film_slope(int a, int b, int k, int l) const {
    double slope = kernel(a - k, b - l);
    if (grid_.mirrored) {
      if (k > 0) slope += kernel(a + k, b - l);
      if (l > 0) slope += kernel(a - k, b + l);
      if (k > 0 && l > 0) slope += kernel(a + k, b + l);
    }
    return slope;
  }
  /// d ln(rho / (eta lambda_bar)) / dP at pressure p: the local part of the
  /// relative change of xi with the pressure (its film part is 3 dH / H).
  [[nodiscard]] double flow_factor_log_slope(double p) const;

  /// |dN_ij / dP_ij| from the frozen coefficients (flow and elastic-squeeze part).
  [[nodiscard]] double diagonal_at(int i, int j) const;
  /// r / |dN_ij/dP_ij| for a residual r of point (i, j); a zero residual (a
  /// held cavitated point) is 0 without the diagonal being formed.
  [[nodiscard]] double pressure_scaled(double r, int i, int j) const {
    return r == 0.0 ? 0.0 : r / diagonal_at(i, j);
  }
  /// Root mean square over the interior of r_ij / |dN_ij/dP_ij|.
  [[nodiscard]] double pressure_scaled_norm(const Field& r) const;

  /// Total force h^2 sum P (P = 0 on the boundary: the trapezoidal rule).
  [[nodiscard]] double force(const Field& P) const;

 private:
  Grid2D grid_;
  Lubricant lubricant_;
  OperatorSettings settings_;
  std::unique_ptr<DeformationOperator> deformation_;
  double dT_ = 1.0;
  double b0_ = 1.0;
  double delta_ = 0.0;
  Field shape_;  ///< X^2/2 + Y^2/2 + waviness: the undeformed gap without Delta
  /// Density, its derivative and rho / (eta lambda_bar) of P, then H and xi
  /// from them, the deformation W_ and Delta, in one pass over the points
  /// (the loops are bound by memory traffic: two passes stream
  /// rho / (eta lambda_bar) and P once more); with `keep_pressure`, P is
  /// also copied into pressure_of_terms_.
  void update_rheology_and_film(const Field& P, bool keep_pressure);
  /// True when the deformation and the rheology were computed for P.
  [[nodiscard]] bool terms_belong_to(const Field& P) const;
  /// H and xi from the pressure terms and Delta.
  void update_film();
  /// H and xi of element k, given its rho / (eta lambda_bar): the one film
  /// formula of update_film() and update_rheology_and_film().
  void set_film_at(std::size_t k, double rho_over_eta_lambda);

  Field W_, H_, rho_, drho_, xi_;
  Field rho_over_eta_lambda_;
  Field pressure_of_terms_;
  bool pressure_terms_valid_ = false;
  long deformation_evaluations_ = 0;
};

}  // namespace ehlsim::reynolds
