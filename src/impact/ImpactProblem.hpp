#pragma once
// The lubricated ball-impact problem (model.md): one class that owns the
// multigrid hierarchy, the ball state and the history of the film, with run()
// marching in time until lift-off or T_end.
#include <functional>
#include <memory>

#include "impact/ImpactConfig.hpp"
#include "impact/ImpactObserver.hpp"
#include "impact/ImpactState.hpp"

namespace ehlsim {

/// True when the solver works on the quadrant X, Y >= 0 with mirror
/// conditions on the axes: solver.symmetry = auto and the case is even in X
/// and Y (the undeformed gap is even when the waviness is absent or runs along
/// an axis, its angle a multiple of 90 degrees).
[[nodiscard]] bool is_mirror_symmetric(const ImpactConfig& config);

class ImpactProblem {
 public:
  /// The config must already be validated and complete (lambda_bar, alpha_bar set).
  explicit ImpactProblem(const ImpactConfig& config);
  ~ImpactProblem();
  ImpactProblem(const ImpactProblem&) = delete;
  ImpactProblem& operator=(const ImpactProblem&) = delete;

  /// Marches from Delta0 until lift-off, rest in the film (or T_end); reports
  /// every step to `observer`.  Throws std::runtime_error when the iteration of
  /// a time step diverges, RunFailure (impact/RunGuards.hpp) when a step breaks
  /// a physics guard or the step cap; a step none of whose attempts converges
  /// is solved in halves, down to dT / 32 (kMaxSplitDepth), and begins in
  /// halves where the two steps before needed them (SplitMemory); an interval
  /// of dT / 32 that still did not converge keeps its best iterate, if that
  /// is at most 100 times above solver.tolerance, and is counted in
  /// RunSummary::unconverged_steps.  Throws RunInterrupted
  /// when observer.stop_requested(): after a step, or after a cycle, which
  /// abandons the step under way (the run ends after the step before it).
  RunSummary run(ImpactObserver& observer);

  [[nodiscard]] const ImpactConfig& config() const;

  /// Continue from `state` (a checkpoint of the same case) instead of starting
  /// at Delta0: the next run() begins with step state.step + 1.  Throws
  /// std::invalid_argument when the fields are not on this problem's grid.
  void restart_from(ImpactState state);

  /// Hand the state to `sink` at the end of every `every`-th step (0: never),
  /// and of the step after which the observer asks to stop, e.g. to write a
  /// checkpoint.
  using StateSink = std::function<void(const ImpactState& state)>;
  void set_state_sink(int every, StateSink sink);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace ehlsim
