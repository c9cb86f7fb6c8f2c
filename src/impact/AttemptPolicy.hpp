#pragma once
// When one attempt of a time step stops cycling (docs/model.md, section 7).
//
// Measured in the pocket collapse on 513^2 (T = 3.99-4.16, every cycle of
// every attempt logged): the attempts that converge do so steadily, at 0.5-0.8
// per cycle, and several fell just short at solver.max_cycles (1.4e-5 against
// a tolerance of 1e-5 after 20 cycles at 0.69 per cycle), which cost a fourth
// attempt and left the step above the tolerance.  The attempts that fail climb
// from their lowest residual by orders of magnitude before they blow up or
// wander; none of the attempts that converged ever rose above 2 times its
// lowest residual.
#include <span>
#include <vector>

namespace ehlsim {

/// What an attempt does after its latest cycle.
enum class AttemptVerdict {
  Continue,    ///< cycle again
  Converged,   ///< below the tolerance
  LostGround,  ///< climbed far above its lowest residual: retry from the start
  Exhausted,   ///< out of cycles (or converging too slowly to use more)
};

/// An attempt whose residual climbs this many times above the lowest it
/// reached has lost its way (above: no converged attempt rose beyond 2 times).
inline constexpr double kLostGroundFactor = 4.0;
/// An attempt still converging steadily at solver.max_cycles may go on up to
/// this many times solver.max_cycles in all ...
inline constexpr int kExtendedCycleFactor = 2;
/// ... when its mean rate over the last kRateWindow cycles ...
inline constexpr int kRateWindow = 4;
/// ... is below this and reaches the tolerance within the extension.
inline constexpr double kSteadyRate = 0.9;

/// Retries of a diverged or stalled step: attempts 1 .. kMaxRetries, each
/// more damped than the last (ImpactProblem.cpp, attempt_damping).
inline constexpr int kMaxRetries = 3;

/// Where the attempts of the next time step begin.  The hard stretches of a
/// run (the spike phase on fine grids, the pocket collapse) last many steps,
/// and there a step needs the attempt its predecessor needed: on 1025^2 every
/// first attempt of the rebound from T = 3.2 on diverged, and in the pocket
/// collapse most steps failed three attempts, the one at damping 0.8 often
/// only after 20 cycles.  So a step starts with the attempt that solved the
/// step before, and after a streak of steps solved that way it tries the next
/// lighter one again: a probe (docs/performance.md: 1025^2, T = 4.10 to
/// lift-off, 635 -> 317 work units per step; T = 3.20-3.35, 101 -> 108).
/// Each probe that fails doubles the streak before the next one, up to
/// kMaxProbeBackoff times; one that succeeds resets it.  In the pocket
/// collapse of 1025^2 every probe at damping 0.8 failed, after 5-20 cycles:
/// 193 of its 1106 cycles (docs/performance.md, "Probes that back off").
struct AttemptMemory {
  int first = 0;          ///< the attempt the next step starts with, in [0, kMaxRetries]
  int streak = 0;         ///< steps solved in a row in attempt `first`, < steps_before_probe
  int failed_probes = 0;  ///< probes in a row that failed, in [0, kMaxProbeBackoff]
  bool probing = false;   ///< `first` is a probe: the step before needed `first + 1`
};
/// Measured on 1025^2: 8 held the damped attempts for too long in the rebound
/// (125 work units per step instead of 108 with 3).
inline constexpr int kStepsBeforeLighterAttempt = 3;
/// The most doublings of the streak before a probe: after three failed
/// probes in a row, a probe every 24 steps.
inline constexpr int kMaxProbeBackoff = 3;

/// A step none of whose attempts converges is solved as two halves, and each
/// half likewise, down to dT / 2^kMaxSplitDepth (impact/ImpactProblem.cpp);
/// only then is the best iterate of an interval kept unconverged.  M = 100,
/// L = 20 on 257^2 kept a quarter at 5.1e-5 (T = 4.1016) and converges every
/// step with eighths; on 513^2 it ended at T = 4.078 with quarters at 1.4e-3,
/// and lifts off with eighths and sixteenths; on 1025^2 it ended at T = 4.0576
/// with sixteenths at 1.4e-3, goes on with thirty-seconds, and kept its last
/// two steps at 6.7e-4 and 3.8e-4 while halving stopped at eighths for an
/// interval within the kept-residual bound (docs/performance.md, "Steps that
/// begin in halves").  Runs whose steps all converge by quarters keep their
/// bits with any depth.
inline constexpr int kMaxSplitDepth = 5;

/// Where a step begins in halves: when the two steps before it both needed
/// halves, it begins with as many halvings as both needed, and after a
/// streak of steps solved so tries the longer interval again (the probes of
/// AttemptMemory).  In the pocket collapse of M = 100, L = 20 on 1025^2 every
/// step from T = 4.05 on failed whole and in halves, each after up to four
/// attempts of 20-40 cycles, before its quarters or eighths converged:
/// 228-799 cycles per step, 80-90 % of them in the intervals that failed
/// (docs/performance.md, "Steps that begin in halves").  A single step that
/// needs halves (M = 1000, L = 20 on 65^2, where the film first carries the
/// load) leaves the next one whole, as do the case maps' few.
struct SplitMemory {
  AttemptMemory begin;  ///< `first`: the halvings the next step begins with
  int last_needed = 0;  ///< the halvings the last step needed, at most kMaxSplitDepth
};

/// The memory after a step that needed `needed` halvings below dT (at least
/// the ones it began with).
[[nodiscard]] SplitMemory remember_split(SplitMemory memory, int needed);

/// The steps to solve in attempt `first` before the next probe.
[[nodiscard]] constexpr int steps_before_probe(int failed_probes) {
  return kStepsBeforeLighterAttempt << failed_probes;
}

/// The memory after a step that started in `memory.first` converged in
/// attempt `converged_in`.
[[nodiscard]] AttemptMemory remember_attempt(AttemptMemory memory, int converged_in);

/// The attempts of a step that begins with attempt `first`, in the order
/// they are made: `first`, the more damped ones up to kMaxRetries, then the
/// lighter ones, `first - 1` down to 0.  In the pocket collapse a step that
/// begins at the most damped attempt has no other: M = 10 on 1025^2 kept the
/// step at T = 3.6885 at 3.1 times the tolerance after its halves and
/// quarters had each failed the one attempt at damping 0.2 (lost ground),
/// where the attempt at 0.4 converged the quarters after them
/// (docs/performance.md).
[[nodiscard]] std::vector<int> attempt_order(int first);

/// The verdict on an attempt whose residuals after cycles 1, 2, ... are
/// `history` (the latest last), given the tolerance and solver.max_cycles.
/// Below the tolerance it has converged if its latest cycle left the force
/// settled (solver.force_tolerance), else it cycles on up to max_cycles and
/// has converged there.
[[nodiscard]] AttemptVerdict judge_attempt(std::span<const double> history, double tolerance,
                                           int max_cycles, bool force_settled = true);

/// Whether an iterate that did not converge may be kept for its step (the
/// best of its attempts), given the film force at the start of the step and
/// its own.  Not one whose pressure vanished where the step began with some:
/// M = 100, L = 20 on 1025^2 kept such an iterate in the collapse of the
/// entrapped pocket (T = 4.034, residual 3.7e-4: the pocket is a few meshes
/// of the grid the residual is averaged over), and the run took it for a
/// lift-off, the force falling from 0.059 to 0 in one step, 0.07 before the
/// lift-off of 513^2.  A pressure that vanishes converges when it is the
/// solution, as at a true lift-off.  Such an iterate is kept only when no
/// other is left, and a run does not take it for a lift-off (ImpactProblem.cpp).
[[nodiscard]] constexpr bool may_keep_unconverged(double start_force, double force) {
  return force > 0.0 || !(start_force > 0.0);
}

}  // namespace ehlsim
