#pragma once
// The spike files (docs/usage.md, "Outputs"), all written atomically:
//
//   spike.csv            in-situ, one row per time step (SpikeOutput)
//   spike_snapshots.csv  offline (`ehlsim spike`), one row per fields.nc snapshot
//   spike_profiles.csv   offline: the filtered P(R) of every snapshot
//   axis_profiles.csv    offline: P(X) on Y = 0 of every snapshot
//
// The series files have the columns T,R_s,P_s,V_s,A_dry,X_s,P_xs; V_s =
// dR_s/dT by finite differences of R_s (three-point, two-point at the ends),
// so a row is written when the next sample is known.
#include <filesystem>
#include <optional>
#include <string_view>

#include "analysis/SpikeAnalysis.hpp"
#include "impact/ImpactConfig.hpp"
#include "impact/ImpactObserver.hpp"
#include "io/CsvWriter.hpp"

namespace ehlsim {

class SpikeSeriesWriter {
 public:
  static constexpr std::string_view kHeader = "T,R_s,P_s,V_s,A_dry,X_s,P_xs";

  explicit SpikeSeriesWriter(const std::filesystem::path& path) : csv_(path, kHeader) {}
  /// Adds a sample (times increasing); writes the row of the one before.
  void append(const SpikeSample& sample);
  /// Takes `sample` as the row before the first one, written by another run
  /// (a restart): the first row's V_s is then the three-point difference the
  /// uninterrupted run has.  Only before the first append().
  void resume_after(const SpikeSample& sample);
  /// Writes the last row and renames the file to its final name.
  void commit();
  [[nodiscard]] std::size_t rows() const { return csv_.rows(); }

 private:
  void write(const SpikeSample& sample, double V_s);

  CsvWriter csv_;
  std::optional<SpikeSample> previous_;  ///< written (or, on a restart, the checkpoint's)
  std::optional<SpikeSample> current_;   ///< waiting for the next sample
};

/// Writes one profile per call as rows "T,<position>,<value>".
class ProfileWriter {
 public:
  ProfileWriter(const std::filesystem::path& path, std::string_view header) : csv_(path, header) {}
  void append(double T, const Profile& profile);
  void commit() { csv_.commit(); }

 private:
  CsvWriter csv_;
};

/// spike.csv during a run: the analysis of every step's pressure field.
class SpikeOutput final : public ImpactObserver {
 public:
  static constexpr std::string_view kFile = "spike.csv";

  /// Creates the directory if missing and opens "<directory>/spike.csv.part".
  SpikeOutput(const std::filesystem::path& directory, const ImpactConfig& config);

  /// The constructor sorted the configuration's grid already (a restart
  /// analyses its checkpoint before the run starts): sorted again only if
  /// the run reports on another grid.
  void on_start(const Grid2D& grid) override {
    if (!(order_.grid() == grid)) order_ = RadialOrder(grid);
  }
  void on_step(const StepRecord& record, const Field& P, const Field& H, bool snapshot) override;
  void on_finish(const RunSummary& summary) override;
  /// A restart from the state after the step at T with pressure P: the
  /// analysis of P gives V_s of the first step after it (see
  /// SpikeSeriesWriter::resume_after).
  void resume_after(double T, const Field& P);

 private:
  SpikeSettings settings_;
  RadialOrder order_;  // of the grid the run reports its fields on
  DryContactRadius dry_;
  std::optional<SpikeSeriesWriter> series_;
};

}  // namespace ehlsim
