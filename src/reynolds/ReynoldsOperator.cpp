#include "reynolds/ReynoldsOperator.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <vector>

namespace ehlsim::reynolds {

namespace {
// Relative step of the finite-difference derivative d rho / d P; rho is smooth
// and O(1), so a step near sqrt(machine epsilon) balances truncation and round-off.
constexpr double kDensityDerivativeStep = 1e-7;
// Step of the one-sided difference of ln(rho / eta): ln(eta) is smooth, with
// slopes up to alpha_bar ~ 30, so the truncation error is about 1e-6 alpha_bar^2
// relative, and the round-off of the log difference about 1e-10.
constexpr double kFlowFactorSlopeStep = 1e-6;
}  // namespace

ReynoldsOperator::ReynoldsOperator(const Grid2D& grid, const Lubricant& lubricant,
                                   const OperatorSettings& settings)
    : grid_(grid),
      lubricant_(lubricant),
      settings_(settings),
      shape_(grid),
      W_(grid),
      H_(grid),
      rho_(grid, 1.0),
      drho_(grid),
      xi_(grid),
      rho_over_eta_lambda_(grid),
      pressure_of_terms_(grid) {
  if (grid_.mirrored && settings_.wedge != 0.0)
    throw std::invalid_argument("ReynoldsOperator: the wedge term is not even in X");
  if (settings_.elastic) deformation_ = make_deformation(grid_, settings_.use_fft);
  for (int j = 0; j < grid_.n; ++j) {
    for (int i = 0; i < grid_.n; ++i) {
      const double x = grid_.x(i), y = grid_.y(j);
      shape_(i, j) =
          0.5 * (x * x + settings_.curvature_ratio * y * y) + settings_.waviness.height(x, y);
    }
  }
}

double ReynoldsOperator::kernel(int di, int dj) const {
  return deformation_ ? deformation_->kernel()(di, dj) : 0.0;
}

double ReynoldsOperator::flow_factor_log_slope(double p) const {
  // The rheology sees max(P, 0) (update_rheology_and_film): no slope below zero.
  if (p < 0.0) return 0.0;
  const auto log_factor = [&](double q) {
    return std::log(lubricant_.rho_bar(q)) - lubricant_.log_eta_bar(q);
  };
  return (log_factor(p + kFlowFactorSlopeStep) - log_factor(p)) / kFlowFactorSlopeStep;
}

inline void ReynoldsOperator::set_film_at(std::size_t k, double rho_over_eta_lambda) {
  const double h = delta_ + shape_[k] + W_[k];
  H_[k] = h;
  // A negative film (possible in early iterates) must not give an
  // anti-diffusive coefficient: the flow factor uses max(H, 0).
  const double hp = std::max(h, 0.0);
  xi_[k] = rho_over_eta_lambda * hp * hp * hp;
}

void ReynoldsOperator::update_coefficients(const Field& P) {
  // The relaxation and the residual often ask again for the pressure of the
  // last update (after the convergence check, the next cycle's first sweep;
  // on a coarse grid, the FAS right-hand side and the first sweep), with at
  // most Delta changed in between: the deformation and the rheology are then
  // reused and only the film is recomputed.
  if (terms_belong_to(P)) {
    update_film();
    return;
  }
  if (deformation_) {
    deformation_->apply(P, W_);
    ++deformation_evaluations_;
  }
  update_rheology_and_film(P, true);
  pressure_terms_valid_ = true;
}

void ReynoldsOperator::update_coefficients_keeping_deformation(const Field& P) {
  if (terms_belong_to(P)) {
    update_film();
    return;
  }
  update_rheology_and_film(P, false);
  // W_ no longer belongs to P: the next full update computes everything.
  pressure_terms_valid_ = false;
}

bool ReynoldsOperator::terms_belong_to(const Field& P) const {
  return pressure_terms_valid_ && equal_values(P, pressure_of_terms_);
}

void ReynoldsOperator::update_rheology_and_film(const Field& P, bool keep_pressure) {
  const double inv_lambda = 1.0 / settings_.lambda_bar;
  // The viscosity at P = 0, evaluated once: in contact much of the domain is
  // cavitated, and the exponential is the costly part of the loop.
  const double eta_zero = lubricant_.eta_bar(0.0);
  // An incompressible density stays at 1 and its derivative at 0, as
  // constructed: not written again (two fewer arrays through memory).
  const bool compressible = lubricant_.density != DensityModel::Incompressible;
  const std::size_t size = grid_.size();
  const bool threaded = worth_threads(grid_);
  // Rows dealt round-robin: the pressurized rows, where the exponential is
  // taken, lie at one end of a quadrant (a static halving gave one thread
  // five times the other's exponentials on 1025^2).
  const auto row = static_cast<std::size_t>(grid_.n);
#pragma omp parallel for schedule(static, row) if (threaded)
  for (std::size_t k = 0; k < size; ++k) {
    const double p = std::max(P[k], 0.0);
    const double rho = lubricant_.rho_bar(p);
    if (compressible) {
      rho_[k] = rho;
      drho_[k] = (lubricant_.rho_bar(p + kDensityDerivativeStep) - rho) / kDensityDerivativeStep;
    }
    const double eta = p > 0.0 ? lubricant_.eta_bar(p) : eta_zero;
    const double rho_over_eta_lambda = rho * inv_lambda / eta;
    rho_over_eta_lambda_[k] = rho_over_eta_lambda;
    set_film_at(k, rho_over_eta_lambda);
    if (keep_pressure) pressure_of_terms_[k] = P[k];
  }
}

void ReynoldsOperator::update_film() {
  const std::size_t size = grid_.size();
  const bool threaded = worth_threads(grid_);
#pragma omp parallel for schedule(static) if (threaded)
  for (std::size_t k = 0; k < size; ++k) set_film_at(k, rho_over_eta_lambda_[k]);
}

double ReynoldsOperator::apply_at(const Field& P, int i, int j, const Faces& faces) const {
  const double h = grid_.h();
  const double p = P(i, j);
  const double flow = (faces.east * (P(i + 1, j) - p) - faces.west * (p - P(i - 1, j)) +
                       faces.north * (P(i, j + 1) - p) - faces.south * (p - P(i, j - 1))) /
                      (h * h);
  return flow - transport_at(i, j, taps_at(i));
}

double ReynoldsOperator::elastic_diagonal(int i, int j) const {
  const TransportTaps taps = taps_at(i);
  double sum = taps.weight[0] * rho_(i, j) * kernel(0, 0);
  for (int t = 1; t < kTransportTaps; ++t)
    if (taps.weight[t] != 0.0) sum += taps.weight[t] * rho_(i - t, j) * kernel(t, 0);
  return sum;
}

void ReynoldsOperator::apply(const Field& P, Field& N) {
  update_coefficients(P);
  const int n = grid_.n;
  const int first = grid_.first_interior();
  N.fill(0.0);
  const bool threaded = worth_threads(grid_);
#pragma omp parallel for schedule(static) if (threaded)
  for (int j = first; j < n - 1; ++j)
    for (int i = first; i < n - 1; ++i) N(i, j) = apply_at(P, i, j);
}

double ReynoldsOperator::diagonal_at(int i, int j) const {
  const Faces faces = faces_at(i, j);
  const double flow =
      (faces.west + faces.east + faces.south + faces.north) / (grid_.h() * grid_.h());
  const TransportTaps taps = taps_at(i);
  double transport = taps.weight[0] * (rho_(i, j) * kernel(0, 0) + drho_(i, j) * H_(i, j));
  for (int t = 1; t < kTransportTaps; ++t)
    if (taps.weight[t] != 0.0) transport += taps.weight[t] * rho_(i - t, j) * kernel(t, 0);
  return flow + transport;
}

double ReynoldsOperator::pressure_scaled_norm(const Field& r) const {
  // Over the full grid's interior (full_interior_sum).
  const double sum = full_interior_sum(grid_, [&](int i, int j) {
    const double scaled = pressure_scaled(r(i, j), i, j);
    return scaled * scaled;
  });
  const double count = grid_.full_interior();
  return std::sqrt(sum / (count * count));
}

double ReynoldsOperator::force(const Field& P) const {
  // The trapezoidal rule over the full grid (P = 0 on its boundary).
  const double h = grid_.h();
  return full_interior_sum(grid_, [&](int i, int j) { return P(i, j); }) * h * h;
}

}  // namespace ehlsim::reynolds
