#pragma once
// How many OpenMP threads a run uses, chosen while it runs from what else the
// machine is doing.  A run's threads meet at several barriers per relaxation
// sweep; when another process holds a core, a thread that waits there for a
// descheduled partner stalls the whole team (measured: a default run took 85 s
// with two threads next to one busy process, 38 s with one thread).  So the
// team shrinks to the cores that are free, and grows again when they are.
// The results do not depend on the thread count (the same bits on 1 and 2
// threads), so the team may change between any two steps.
#include <deque>
#include <functional>
#include <string_view>

#include "impact/ImpactObserver.hpp"

namespace ehlsim {

/// Counts of runnable tasks, as the kernel reports them.
struct RunnableTasks {
  int machine = 0;  ///< running or runnable tasks on the machine (/proc/stat, procs_running)
  int own = 0;      ///< ... of them, threads of this process (/proc/self/task/*/stat)
};

/// Reads the counts from /proc; nullopt-like {-1, -1} where /proc cannot be read.
[[nodiscard]] RunnableTasks read_runnable_tasks();

class ThreadBudget final : public ImpactObserver {
 public:
  /// `cores`: the most threads to use.  `sample` reads the runnable tasks
  /// (replaceable for tests); `set_threads` applies a thread count.
  ThreadBudget(int cores, std::function<RunnableTasks()> sample = read_runnable_tasks,
               std::function<void(int)> set_threads = nullptr);

  /// Samples the machine at most every kSampleSeconds and sets the team to
  /// the cores that the other processes left free (at least one), judged on
  /// the mean of the last kSamples samples.
  void on_step(const StepRecord& record, const Field& P, const Field& H, bool snapshot) override;
  /// The same within a step and in the solve at T = 0, which can take many
  /// seconds without a step: two runs started together kept both their
  /// two-thread teams through it, spinning against each other, and took 3.6
  /// and 4.3 times the solo time instead of 1.5 (docs/performance.md,
  /// "Threads and a shared machine").
  void on_cycle(const CycleRecord& record) override;
  void on_initial_cycle(int cycle, double residual) override;
  /// The same decision from one sample (for tests): returns the thread count.
  int update(const RunnableTasks& sample);
  [[nodiscard]] int threads() const { return threads_; }

 private:
  int cores_;
  int threads_;
  std::function<RunnableTasks()> sample_;
  std::function<void(int)> set_threads_;
  /// Samples the machine if kSampleSeconds have passed since the last sample.
  void sample_when_due();
  std::deque<int> others_;  ///< other processes' runnable tasks in the last samples
  double last_sample_ = -1.0;
};

/// True when the user fixed the thread count (OMP_NUM_THREADS set): then the
/// budget is not applied.
[[nodiscard]] bool user_set_thread_count();

/// The cores this process may run on (its CPU affinity), at least 1.
[[nodiscard]] int available_cores();

/// The team size of OMP_NUM_THREADS (`value`; its first entry when it lists
/// one per nesting level, "2,1"), at most `cores`: more threads than cores
/// only wait for each other, and OMP_NUM_THREADS=100000 crashed libgomp in the
/// first parallel region.  ConfigError naming the variable for a value that is
/// not a whole number >= 1 (which libgomp ignores, with a warning).
[[nodiscard]] int user_thread_count(std::string_view value, int cores);

/// Applies OMP_NUM_THREADS, if set, through user_thread_count before the
/// first parallel region.
void apply_user_thread_count();

}  // namespace ehlsim
