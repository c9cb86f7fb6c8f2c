#include "multigrid/Fas.hpp"

#include <cmath>
#include <stdexcept>

#include "multigrid/Transfer.hpp"

namespace ehlsim::multigrid {

FasSolver::FasSolver(std::vector<FasLevel*> levels, FasSettings settings)
    : levels_(std::move(levels)), settings_(settings) {
  if (levels_.empty()) throw std::invalid_argument("FasSolver: no levels");
  for (std::size_t l = 1; l < levels_.size(); ++l) {
    if (levels_[l]->grid().n != levels_[l - 1]->grid().coarser().n)
      throw std::invalid_argument("FasSolver: levels are not a standard coarsening sequence");
  }
  for (auto* level : levels_) {
    u_.emplace_back(level->grid());
    f_.emplace_back(level->grid());
    r_.emplace_back(level->grid());
    u_coarse_old_.emplace_back(level->grid());
    scratch_.emplace_back(level->grid());
    saved_.emplace_back(level->grid());
  }
}

void FasSolver::cycle_on(int l) {
  FasLevel& level = *levels_[l];
  if (l == num_levels() - 1) {
    level.relax(u_[l], f_[l], settings_.coarsest_sweeps);
    return;
  }
  level.relax(u_[l], f_[l], settings_.pre_sweeps);

  // FAS coarse problem: N_c(u_c) = N_c(I u) + R (f - N(u)).
  FasLevel& coarse = *levels_[l + 1];
  level.residual(u_[l], f_[l], r_[l]);
  const bool safeguard = settings_.correction_safeguard > 0.0;
  const double residual_before = safeguard ? level.norm(r_[l]) : 0.0;
  inject(u_[l], u_[l + 1]);
  restrict_full_weighting(r_[l], f_[l + 1]);
  coarse.apply(u_[l + 1], scratch_[l + 1]);
  add_to(scratch_[l + 1], f_[l + 1]);
  u_coarse_old_[l + 1] = u_[l + 1];

  for (int visit = 0; visit < settings_.cycle_index; ++visit) cycle_on(l + 1);

  // Correction: u += P (u_c - I u).
  Field& correction = scratch_[l + 1];
  difference(u_[l + 1], u_coarse_old_[l + 1], correction);
  Field& fine_correction = r_[l];  // the residual is not needed any more
  fine_correction.fill(0.0);
  prolong_bilinear_add(correction, fine_correction);
  if (safeguard) saved_[l] = u_[l];
  level.correct(u_[l], fine_correction);
  if (safeguard) {
    Field& residual_after = scratch_[l];  // free while this level is being cycled
    level.residual(u_[l], f_[l], residual_after);
    const double after = level.norm(residual_after);
    if (!(after <= settings_.correction_safeguard * residual_before)) {
      u_[l] = saved_[l];
      ++rejected_corrections_;
    }
  }

  level.relax(u_[l], f_[l], settings_.post_sweeps);
}

void FasSolver::restrict_rhs_to_coarse_levels() {
  for (int l = 0; l + 1 < num_levels(); ++l) restrict_full_weighting(f_[l], f_[l + 1]);
}

void FasSolver::interpolate_solution(int level) {
  prolong_cubic(u_[level + 1], u_[level]);
  levels_[level]->project(u_[level]);
}

void FasSolver::full_multigrid() {
  const int coarsest = num_levels() - 1;
  restrict_rhs_to_coarse_levels();
  levels_[coarsest]->relax(u_[coarsest], f_[coarsest], settings_.coarsest_sweeps);
  for (int l = coarsest - 1; l >= 0; --l) {
    interpolate_solution(l);
    for (int c = 0; c < settings_.fmg_cycles; ++c) cycle_on(l);
  }
}

void FasLevel::correct(Field& u, const Field& correction) {
  add_to(correction, u);
  project(u);
}

double FasLevel::norm(const Field& r) {
  const Grid2D& g = grid();
  const double sum = full_interior_sum(g, [&](int i, int j) { return r(i, j) * r(i, j); });
  const double count = g.full_interior();
  return std::sqrt(sum / (count * count));
}

double FasSolver::residual_norm(int level) {
  levels_[level]->residual(u_[level], f_[level], r_[level]);
  return levels_[level]->norm(r_[level]);
}

}  // namespace ehlsim::multigrid
