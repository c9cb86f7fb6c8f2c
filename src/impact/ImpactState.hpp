#pragma once
// The state of an impact run at the end of a time step: everything run() needs
// to go on from there.  A checkpoint (io/Checkpoint.hpp) stores it, a restart
// (ImpactProblem::restart_from) continues from it.
#include "dynamics/Newmark.hpp"
#include "grid/Grid.hpp"
#include "impact/AttemptPolicy.hpp"
#include "impact/ImpactObserver.hpp"

namespace ehlsim {

struct ImpactState {
  int step = 0;               ///< time steps done
  BallState ball;             ///< the ball at the end of step `step`
  double force = 0.0;         ///< film force at the last time level
  double force_before = 0.0;  ///< ... and at the one before (the force extrapolation)
  bool had_pressure = false;  ///< some step so far carried pressure (lift-off needs it)
  RunSummary summary;         ///< extremes, impulse and solver counters up to `step`
  AttemptMemory attempts;     ///< where the next step's attempts begin
  SplitMemory splits;         ///< in how many halvings the next step begins
  Field P;                    ///< pressure at the last time level (finest grid)
  Field P_before;             ///< pressure at the level before (the extrapolated start)
  Field P_before2;            ///< ... and at the one before that (the quadratic start)
  Field P_before3;            ///< ... and at the one before that (the cubic start)
  Field rhoH;                 ///< rho H at the last time level (the BDF2 history)
  Field rhoH_before;          ///< rho H at the level before
};

}  // namespace ehlsim
