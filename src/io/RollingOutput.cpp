#include "io/RollingOutput.hpp"

#include <fmt/format.h>

#include <cmath>
#include <utility>

#include "config/RollingParameters.hpp"
#include "io/AtomicFile.hpp"
#include "io/CsvWriter.hpp"
#include "io/FieldWriter.hpp"
#include "io/ProgramInfo.hpp"
#include "reynolds/LineRelaxation.hpp"
#include "rolling/FilmFormula.hpp"

namespace ehlsim {

namespace {
/// Index of the grid line nearest to coordinate v (origin v0, mesh size h).
int nearest_index(double v, double v0, double h, int n) {
  const long i = std::lround((v - v0) / h);
  return static_cast<int>(std::clamp<long>(i, 0, n - 1));
}

void write_profiles(const std::filesystem::path& dir, const RollingResult& r) {
  const Grid2D& g = r.grid;
  const int j0 = nearest_index(0.0, g.y(0), g.h(), g.n);
  CsvWriter along_x(dir / "profile_x.csv", "X,P,H");
  for (int i = 0; i < g.n; ++i)
    along_x.append(fmt::format("{:.10g},{:.10g},{:.10g}", g.x(i), r.P(i, j0), r.H(i, j0)));
  const int i_m = nearest_index(r.X_Hm, g.x(0), g.h(), g.n);
  CsvWriter along_y(dir / "profile_y.csv", "Y,P,H");
  for (int j = 0; j < g.n; ++j)
    along_y.append(fmt::format("{:.10g},{:.10g},{:.10g}", g.y(j), r.P(i_m, j), r.H(i_m, j)));
  CsvWriter history(dir / "convergence.csv",
                    "points,cycle,attempt,damping,residual,force_error,Hc,H0,work,"
                    "deformation_updates");
  for (const RollingCycle& c : r.history)
    history.append(fmt::format("{},{},{},{:g},{:.6e},{:.6e},{:.10g},{:.10g},{:.2f},{}", c.points,
                               c.cycle, c.attempt, c.damping, c.residual, c.force_error, c.Hc, c.H0,
                               c.work, reynolds::deformation_updates_text(c.each_colour)));
  along_x.commit();
  along_y.commit();
  history.commit();
}
}  // namespace

nlohmann::json rolling_results_json(const RollingConfig& c, const RollingResult& r) {
  return {{"Hc", r.Hc},
          {"X_Hc", 0.0},
          {"Y_Hc", 0.0},
          {"Hm", r.Hm},
          {"X_Hm", r.X_Hm},
          {"Y_Hm", r.Y_Hm},
          {"Hc_moes", hertz_to_moes_film(r.Hc, c.M)},
          {"Hm_moes", hertz_to_moes_film(r.Hm, c.M)},
          {"Hc_moes_nvm", r.Hc_moes_nvm},
          {"Hc_deviation_from_nvm", r.nvm_deviation},
          {"H0", r.H0},
          {"P_max", r.P_max},
          {"X_P_max", r.X_P_max},
          {"Y_P_max", r.Y_P_max},
          {"residual", r.residual},
          {"force_error", r.force_error},
          {"cycles", r.cycles},
          {"work_units", r.work},
          {"deformation_updates", reynolds::deformation_updates_text(r.each_colour)},
          {"fallback_after_cycles", r.fallback_after},
          {"edge_load_share", r.edge_load},
          {"warnings", r.warnings}};
}

void write_rolling_run(const std::filesystem::path& dir, const RollingConfig& config,
                       const RollingResult& result, const nlohmann::json& invocation,
                       double wall_seconds) {
  const nlohmann::json parameters = rolling_parameters_json(config);
  FieldLayout layout = FieldLayout::impact(result.grid);
  layout.title = "ehlsim: steady rolling EHL point contact (pressure and film thickness)";
  // Hertz units of the rolling contact (docs/model.md, section 11): a is the
  // dry contact's radius along X; one record, the steady solution.
  layout.time_name = "record of the steady solution (0; no time dependence)";
  layout.x_name = "dimensionless coordinate X = x / a (along the rolling)";
  layout.y_name = "dimensionless coordinate Y = y / a";
  layout.film_name = "dimensionless film thickness H = h Rx / a^2";
  FieldWriter fields(dir / "fields.nc", std::move(layout), parameters);
  fields.append(0.0, result.P, result.H);
  write_profiles(dir, result);
  fields.commit();
  nlohmann::json j;
  j["program"] = program_json("rolling");
  if (!invocation.empty()) j["invocation"] = invocation;
  j["parameters"] = parameters;
  j["grid"] = {{"points", result.grid.n},
               {"h", result.grid.h()},
               {"x_min", result.grid.x(0)},
               {"y_min", result.grid.y(0)}};
  j["results"] = rolling_results_json(config, result);
  j["wall_seconds"] = wall_seconds;
  j["files"] = {{"fields", "fields.nc"},
                {"profile_x", "profile_x.csv"},
                {"profile_y", "profile_y.csv"},
                {"convergence", "convergence.csv"}};
  write_json_atomic(dir / "run.json", j);
}

}  // namespace ehlsim
