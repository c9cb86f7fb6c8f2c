#include "io/ThreadBudget.hpp"

#include <fmt/format.h>
#include <omp.h>
#include <sched.h>

#include <algorithm>
#include <charconv>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <numeric>
#include <sstream>
#include <string>
#include <thread>

#include "config/ParameterSet.hpp"

namespace ehlsim {

namespace {
/// Seconds between two samples: reading /proc costs about 0.1 ms, and a
/// process that starts or ends is noticed within a second.
constexpr double kSampleSeconds = 0.2;
/// Samples averaged for a decision (about a second): one sample catches
/// short-lived tasks (a shell command, a compiler starting) as often as
/// lasting ones.
constexpr std::size_t kSamples = 5;

double now_seconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

/// procs_running of /proc/stat, or -1.
int machine_running() {
  std::ifstream stat("/proc/stat");
  std::string key;
  while (stat >> key) {
    if (key == "procs_running") {
      int count = -1;
      stat >> count;
      return count;
    }
    stat.ignore(std::numeric_limits<std::streamsize>::max(), '\n');  // the rest of the line
  }
  return -1;
}

/// Threads of this process in state R (running or runnable), or -1.
int own_running() {
  std::error_code error;
  int count = 0;
  for (const auto& task : std::filesystem::directory_iterator("/proc/self/task", error)) {
    std::ifstream stat(task.path() / "stat");
    std::string line;
    if (!std::getline(stat, line)) continue;
    // "tid (comm) S ...": the state follows the last ')' (comm may hold spaces).
    const auto close = line.rfind(')');
    if (close != std::string::npos && close + 2 < line.size() && line[close + 2] == 'R') ++count;
  }
  return error ? -1 : count;
}
}  // namespace

RunnableTasks read_runnable_tasks() { return {machine_running(), own_running()}; }

bool user_set_thread_count() { return std::getenv("OMP_NUM_THREADS") != nullptr; }

int available_cores() {
  cpu_set_t set;
  CPU_ZERO(&set);
  if (sched_getaffinity(0, sizeof(set), &set) == 0) return std::max(1, CPU_COUNT(&set));
  return std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
}

int user_thread_count(std::string_view value, int cores) {
  // OpenMP allows blanks around the number and a list, one per nesting level.
  const std::string_view first = value.substr(0, value.find(','));
  const std::size_t begin = first.find_first_not_of(" \t");
  const std::size_t end = first.find_last_not_of(" \t");
  const std::string_view digits =
      begin == std::string_view::npos ? std::string_view() : first.substr(begin, end - begin + 1);
  long long threads = 0;
  const bool decimal =
      !digits.empty() && digits.find_first_not_of("0123456789") == std::string_view::npos;
  // Beyond the range of long long: a huge count, so the cores.
  const bool huge =
      decimal && std::from_chars(digits.data(), digits.data() + digits.size(), threads).ec ==
                     std::errc::result_out_of_range;
  if (!decimal || (!huge && threads < 1)) {
    throw ConfigError(fmt::format("OMP_NUM_THREADS = '{}': must be a whole number of threads >= 1 "
                                  "(unset: ehlsim chooses them from the cores that are free)",
                                  echo_input(value)),
                      "OMP_NUM_THREADS");
  }
  return huge ? cores : static_cast<int>(std::min<long long>(threads, cores));
}

void apply_user_thread_count() {
  const char* value = std::getenv("OMP_NUM_THREADS");
  if (value != nullptr) omp_set_num_threads(user_thread_count(value, available_cores()));
}

ThreadBudget::ThreadBudget(int cores, std::function<RunnableTasks()> sample,
                           std::function<void(int)> set_threads)
    : cores_(std::max(1, cores)),
      threads_(std::max(1, cores)),
      sample_(std::move(sample)),
      set_threads_(set_threads ? std::move(set_threads) : [](int n) { omp_set_num_threads(n); }) {}

void ThreadBudget::on_step(const StepRecord&, const Field&, const Field&, bool) {
  sample_when_due();
}

void ThreadBudget::on_cycle(const CycleRecord&) { sample_when_due(); }

void ThreadBudget::on_initial_cycle(int, double) { sample_when_due(); }

void ThreadBudget::sample_when_due() {
  const double now = now_seconds();
  if (last_sample_ >= 0.0 && now - last_sample_ < kSampleSeconds) return;
  last_sample_ = now;
  const int before = threads_;
  update(sample_());
  if (threads_ != before) set_threads_(threads_);
}

int ThreadBudget::update(const RunnableTasks& sample) {
  if (sample.machine < 0 || sample.own < 0) return threads_;  // no /proc: keep the team
  others_.push_back(std::max(0, sample.machine - sample.own));
  if (others_.size() > kSamples) others_.pop_front();
  const double mean = static_cast<double>(std::accumulate(others_.begin(), others_.end(), 0)) /
                      static_cast<double>(others_.size());
  // Cores the others leave free, rounded to the nearest whole core.
  const int free_cores = cores_ - static_cast<int>(mean + 0.5);
  threads_ = std::clamp(free_cores, 1, cores_);
  return threads_;
}

}  // namespace ehlsim
