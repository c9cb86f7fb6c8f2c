#pragma once
// Several observers of one run, called in the order given (e.g. spike.csv
// before RunOutput, whose run.json must be the last file to appear).
#include <algorithm>
#include <utility>
#include <vector>

#include "impact/ImpactObserver.hpp"

namespace ehlsim {

class ObserverChain final : public ImpactObserver {
 public:
  explicit ObserverChain(std::vector<ImpactObserver*> observers)
      : observers_(std::move(observers)) {}

  void on_start(const Grid2D& grid) override {
    for (ImpactObserver* o : observers_) o->on_start(grid);
  }
  void on_step(const StepRecord& record, const Field& P, const Field& H, bool snapshot) override {
    for (ImpactObserver* o : observers_) o->on_step(record, P, H, snapshot);
  }
  void on_cycle(const CycleRecord& record) override {
    for (ImpactObserver* o : observers_) o->on_cycle(record);
  }
  void on_initial_cycle(int cycle, double residual) override {
    for (ImpactObserver* o : observers_) o->on_initial_cycle(cycle, residual);
  }
  void on_finish(const RunSummary& summary) override {
    for (ImpactObserver* o : observers_) o->on_finish(summary);
  }
  [[nodiscard]] bool stop_requested() const override {
    return std::any_of(observers_.begin(), observers_.end(),
                       [](const ImpactObserver* o) { return o->stop_requested(); });
  }

 private:
  std::vector<ImpactObserver*> observers_;
};

}  // namespace ehlsim
