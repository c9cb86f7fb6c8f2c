#include "impact/AttemptPolicy.hpp"

#include <algorithm>
#include <cmath>

namespace ehlsim {

namespace {
/// The mean reduction per cycle over the last kRateWindow cycles.
double recent_rate(std::span<const double> history) {
  const double now = history.back();
  const double before = history[history.size() - 1 - kRateWindow];
  return std::pow(now / before, 1.0 / kRateWindow);
}

/// True when the attempt converges steadily enough to reach the tolerance
/// within the cycles of the extension.
bool worth_extending(std::span<const double> history, double tolerance, int max_cycles) {
  const int cycles = static_cast<int>(history.size());
  const int cap = kExtendedCycleFactor * max_cycles;
  if (cycles >= cap || cycles <= kRateWindow) return false;
  const double rate = recent_rate(history);
  if (!(rate < kSteadyRate)) return false;
  const double cycles_needed = std::log(tolerance / history.back()) / std::log(rate);
  return cycles_needed <= cap - cycles;
}
}  // namespace

std::vector<int> attempt_order(int first) {
  std::vector<int> order;
  for (int attempt = first; attempt <= kMaxRetries; ++attempt) order.push_back(attempt);
  for (int attempt = first - 1; attempt >= 0; --attempt) order.push_back(attempt);
  return order;
}

AttemptMemory remember_attempt(AttemptMemory memory, int converged_in) {
  if (converged_in > memory.first) {
    const int failed_probes = memory.probing ? std::min(memory.failed_probes + 1, kMaxProbeBackoff)
                                             : memory.failed_probes;
    return {converged_in, 0, failed_probes, false};
  }
  if (memory.probing) memory.failed_probes = 0;
  memory.probing = false;
  if (memory.first == 0 || ++memory.streak < steps_before_probe(memory.failed_probes))
    return memory;
  return {memory.first - 1, 0, memory.failed_probes, true};
}

SplitMemory remember_split(SplitMemory memory, int needed) {
  needed = std::min(needed, kMaxSplitDepth);
  // What this step and the one before both needed, and never less than
  // this step began with.
  const int both = std::min(needed, std::max(memory.last_needed, memory.begin.first));
  memory.begin = remember_attempt(memory.begin, both);
  memory.last_needed = needed;
  return memory;
}

AttemptVerdict judge_attempt(std::span<const double> history, double tolerance, int max_cycles,
                             bool force_settled) {
  const double now = history.back();
  if (now < tolerance) {
    const bool out_of_cycles = static_cast<int>(history.size()) >= max_cycles;
    return force_settled || out_of_cycles ? AttemptVerdict::Converged : AttemptVerdict::Continue;
  }
  const auto before = history.first(history.size() - 1);
  if (!before.empty() && now > kLostGroundFactor * *std::min_element(before.begin(), before.end()))
    return AttemptVerdict::LostGround;
  if (static_cast<int>(history.size()) < max_cycles) return AttemptVerdict::Continue;
  return worth_extending(history, tolerance, max_cycles) ? AttemptVerdict::Continue
                                                         : AttemptVerdict::Exhausted;
}

}  // namespace ehlsim
