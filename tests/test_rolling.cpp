// The steady rolling point contact: the film formula, the Hertz limit, the
// film against Nijenbanning, Venner & Moes (1994), and the convergence.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "rolling/FilmFormula.hpp"
#include "rolling/RollingProblem.hpp"

namespace ehlsim {
namespace {

RollingConfig rolling_case(double M, double L, int points) {
  RollingConfig c;
  c.M = M;
  c.L = L;
  c.lambda_bar = std::cbrt(128.0 * std::pow(M_PI, 3) / (3.0 * std::pow(M, 4)));
  c.alpha_bar = L / M_PI * std::cbrt(1.5 * M);
  c.grid_points = points;
  return c;
}

TEST(Rolling, Explore) {
  for (int n : {65, 129}) {
    RollingConfig c = rolling_case(100, 10, n);
    RollingProblem problem(c);
    const RollingResult r = problem.run([](const RollingCycle& cy) {
      std::printf("%4d %3d res %.3e ferr %+.3e Hc %.6f H0 %.6f work %.1f\n", cy.points, cy.cycle,
                  cy.residual, cy.force_error, cy.Hc, cy.H0, cy.work);
    });
    std::printf("n %d Hc %.5f moes %.4f formula %.4f Hm %.5f Pmax %.4f\n", n, r.Hc,
                hertz_to_moes_film(r.Hc, c.M), nvm_central_film(c.M, c.L), r.Hm, r.P_max);
  }
}

}  // namespace
}  // namespace ehlsim
