// The config component: the parameter registry of every mode (defaults,
// ranges and docs declared once), the TOML reader and --set, the messages of
// bad input, the [physical] section's Moes groups and scales, and the echo
// of the effective parameters.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/resource.h>
#include <unistd.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "config/Parameters.hpp"
#include "config/RollingParameters.hpp"
#include "config/SystemFailure.hpp"
#include "dynamics/DryHertz.hpp"
#include "impact/ImpactConfig.hpp"
#include "impact/Scaling.hpp"
#include "rheology/Lubricant.hpp"
#include "support/SteelBall.hpp"
#include "support/TempDir.hpp"
#include "support/TestPaths.hpp"
#include "support/TextFiles.hpp"

namespace ehlsim {
namespace {

namespace fs = std::filesystem;

using ehlsim::testing::source_dir;
using ehlsim::testing::TempDir;
using ehlsim::testing::write_file;

/// A double in full precision, as TOML accepts it.
std::string fmt_double(double v) {
  std::array<char, 64> buffer{};
  std::snprintf(buffer.data(), buffer.size(), "%.17g", v);
  return buffer.data();
}

/// The message of the ConfigError that load_config throws ("" if none).
std::string config_error(const std::optional<fs::path>& file,
                         const std::vector<std::string>& sets) {
  try {
    (void)load_config(file, sets);
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

std::string set_error(const std::vector<std::string>& sets) {
  return config_error(std::nullopt, sets);
}

// ---------------------------------------------------------------------------
// Registry
// ---------------------------------------------------------------------------

TEST(RegistryErrors, AWavinessTheGridSamplesAsAnotherWaveIsRefused) {
  // 33^2 on [-1.5, 1.5]^2: h = 3/32; along X the limit is two meshes, at 45
  // degrees two meshes times cos 45.
  const std::vector<std::string> wavy{"grid.points=33", "surface.waviness_amplitude=0.1"};
  const auto with = [&](std::vector<std::string> sets) {
    sets.insert(sets.begin(), wavy.begin(), wavy.end());
    return sets;
  };
  EXPECT_EQ(set_error(with({"surface.waviness_wavelength=0.18"})),
            "surface.waviness_wavelength = 0.18: must be > 0.1875 on this grid (two meshes along "
            "the wave, the shortest wave the grid does not sample as another one) (--set)");
  EXPECT_EQ(load_config(std::nullopt, with({"surface.waviness_wavelength=0.19"})).grid_points, 33);
  EXPECT_EQ(set_error(with({"surface.waviness_wavelength=0.13", "surface.waviness_angle_deg=45"})),
            "surface.waviness_wavelength = 0.13: must be > 0.1326 on this grid (two meshes along "
            "the wave, the shortest wave the grid does not sample as another one) (--set)");
  // Without an amplitude there is no wave to sample.
  EXPECT_EQ(
      load_config(std::nullopt, {"grid.points=33", "surface.waviness_wavelength=0.01"}).grid_points,
      33);
}

TEST(RegistryErrors, TheDryContactMustFitTheDomainAndSpanFourTimeSteps) {
  // The largest dry contact radius is 1.0456 V0^(2/5) and the contact lasts
  // 3.2181 V0^(-1/5) (model.md, "Reference values").
  const double radius = std::sqrt(std::pow(1.25, 0.4));
  EXPECT_NEAR(dry_largest_contact_radius(1.0), radius, 1e-15);
  EXPECT_NEAR(radius, 1.0456, 1e-4);
  EXPECT_NEAR(dry_largest_contact_radius(32.0), 4.0 * radius, 1e-12);
  EXPECT_NEAR(dry_contact_duration(1.0 / 32.0), 2.0 * kDryContactDuration, 1e-12);
  EXPECT_EQ(set_error({"grid.half_width=1"}),
            "grid.half_width = 1: must be > 1.046, the largest radius of the dry contact at "
            "time.V0 = 1: the domain must hold the contact (the paper's is 1.5) (--set)");
  EXPECT_EQ(load_config(std::nullopt, {"grid.half_width=1.05"}).half_width, 1.05);
  // A default that a given value rules out is named with its value.
  EXPECT_EQ(set_error({"time.V0=32"}),
            "grid.half_width = 1.5 (the default): must be > 4.183, the largest radius of the dry "
            "contact at time.V0 = 32: the domain must hold the contact (the paper's is 1.5)");
  EXPECT_EQ(set_error({"time.dT=0.81"}),
            "time.dT = 0.81: must be <= 0.8045: the dry contact at time.V0 = 1 lasts 3.218, and a "
            "run needs at least 4 steps in it (--set)");
  EXPECT_EQ(load_config(std::nullopt, {"time.dT=0.8"}).dT, 0.8);
  // The mesh is the default time step.
  EXPECT_EQ(set_error({"grid.points=33", "grid.half_width=14"}),
            "grid.half_width = 14: gives a mesh, and so a default time.dT, of 0.875; it must be <= "
            "0.8045 (the dry contact at time.V0 = 1 lasts 3.218, and a run needs at least 4 steps "
            "in it): set time.dT or use a finer mesh (--set)");
  EXPECT_EQ(
      load_config(std::nullopt, {"grid.points=33", "grid.half_width=14", "time.dT=0.1"}).half_width,
      14.0);
  // A mesh wider than the contact's radius cannot resolve it, whatever the time step.
  EXPECT_EQ(set_error({"grid.points=33", "grid.half_width=50", "time.dT=0.1"}),
            "grid.half_width = 50: gives a mesh of 3.125, not below the wider of the squeeze film "
            "at the start, sqrt(2 time.Delta0) = 1.414, and the largest radius of the dry contact "
            "at time.V0 = 1, 1.046: the grid cannot resolve the film; use more points or a "
            "smaller domain (--set)");
  // A rigid ball has no dry contact, but a squeeze film to resolve.
  EXPECT_EQ(set_error({"body.elastic=false", "grid.points=33", "grid.half_width=100"}),
            "grid.half_width = 100: gives a mesh of 6.25, not below the width of the squeeze film "
            "at the start, sqrt(2 time.Delta0) = 1.414: the grid cannot resolve the film; use "
            "more points or a smaller domain (--set)");
  // A rigid ball has no dry contact.
  EXPECT_EQ(load_config(std::nullopt, {"body.elastic=false", "grid.half_width=0.5"}).half_width,
            0.5);
}

TEST(RegistryErrors, MoesGroupsMustBeNumbers) {
  // case.M = 1e300 gives lambda_bar = (128 pi^3 / (3 M^4))^(1/3) = 0: the run
  // diverged at step 11 with "residual -nan".  In SI units a radius of
  // 1e300 m gives W = 0 and M = 0 x inf: named by the section.
  EXPECT_EQ(set_error({"case.M=1e300"}),
            "case.M = 1e+300: gives M = 1e+300, L = 10, lambda_bar = 0 and alpha_bar = "
            "3.64374e+100, which must be finite numbers (M and lambda_bar > 0, L and alpha_bar "
            ">= 0) (--set)");
  EXPECT_NE(
      set_error({"case.lambda_bar=1e-300"}).find("case.lambda_bar = 1e-300: gives M = not finite"),
      std::string::npos);
  EXPECT_EQ(
      set_error({"physical.reduced_radius=1e300", "physical.ball_mass=1", "physical.impact_speed=1",
                 "physical.reduced_modulus=2.2e11", "physical.eta0=0.04", "physical.alpha=2e-8"})
          .rfind("physical: the section's values give M = 0, L = not finite", 0),
      0u);
  // The check is on the arithmetic, not the physics: M = 1e-3 and 1e6, far
  // beyond the paper's cases, still load.
  EXPECT_NO_THROW((void)load_config(std::nullopt, {"case.M=1e-3"}));
  EXPECT_NO_THROW((void)load_config(std::nullopt, {"case.M=1e6"}));
}

TEST(Registry, AutoCoarseFaceMeanIsLogarithmicForImpactsFromL20) {
  // The logarithmic coarse levels save work from L = 20 on and cost some at
  // L = 10 (docs/performance.md); in the rolling contact they are harmful.
  using ehlsim::FaceMean;
  const auto coarse = [](std::vector<std::string> overrides) {
    return load_config(std::nullopt, overrides).coarse_face_mean;
  };
  EXPECT_EQ(coarse({"case.L=20"}), FaceMean::Logarithmic);
  EXPECT_EQ(coarse({"case.L=35", "solver.coarse_face_mean=auto"}), FaceMean::Logarithmic);
  EXPECT_EQ(coarse({"case.L=19.9"}), std::nullopt);
  EXPECT_EQ(coarse({}), std::nullopt);  // the default case, L = 10
  EXPECT_EQ(coarse({"case.L=20", "solver.coarse_face_mean=same"}), std::nullopt);
  EXPECT_EQ(coarse({"case.L=5", "solver.coarse_face_mean=harmonic"}), FaceMean::Harmonic);
  // The L of a Roelands law's own pressure-viscosity decides too.
  for (const char* z : {"lubricant.z=0.68", "lubricant.z=1.5"}) {
    const ehlsim::ImpactConfig roelands = load_config(
        std::nullopt,
        {"lubricant.viscosity=roelands", "lubricant.eta0=0.04", "lubricant.ph_star=1e9", z});
    EXPECT_EQ(roelands.coarse_face_mean,
              roelands.L >= 20.0 ? std::optional(FaceMean::Logarithmic) : std::nullopt)
        << z << ": L = " << roelands.L;
  }
  // run.json records the mean the run used.
  EXPECT_EQ(ehlsim::effective_parameters_json(load_config(std::nullopt, {"case.L=20"}))
                .at("solver")
                .at("coarse_face_mean"),
            "logarithmic");
  EXPECT_EQ(ehlsim::load_rolling_config(std::nullopt, {"case.L=20"}).coarse_face_mean,
            std::nullopt);
}

TEST(Registry, KeysAreUniqueDocumentedAndInKnownSections) {
  std::set<std::string> keys;
  std::set<std::string> sections;
  for (const auto& s : parameter_sections()) sections.insert(s.name);
  for (const auto& spec : parameter_registry()) {
    SCOPED_TRACE(spec.key);
    EXPECT_TRUE(keys.insert(spec.key).second) << "declared twice";
    EXPECT_TRUE(sections.count(std::string(spec.section())));
    EXPECT_FALSE(spec.name().empty());
    EXPECT_FALSE(spec.doc.empty());
    EXPECT_EQ(spec.doc.find('\n'), std::string::npos);
    EXPECT_EQ(find_parameter(spec.key), &spec);
  }
  EXPECT_EQ(find_parameter("case.Mx"), nullptr);
}

TEST(Registry, HelpListsEveryKeyWithDefaultAndRange) {
  const std::string help = describe_parameters();
  for (const auto& spec : parameter_registry()) {
    SCOPED_TRACE(spec.key);
    const std::string line = spec.key + " = " + spec.default_description();
    EXPECT_NE(help.find(line), std::string::npos);
    EXPECT_NE(help.find(spec.allowed()), std::string::npos);
  }
  EXPECT_NE(help.find("grid.points = 257  (integer, 2^k + 1 between 9 and 4097)"),
            std::string::npos);
  EXPECT_NE(help.find("case.M = 100  (float, > 0)"), std::string::npos);
  EXPECT_NE(help.find("lubricant.viscosity = \"barus\"  (string, one of \"barus\", \"roelands\")"),
            std::string::npos);
  EXPECT_NE(help.find("physical.nu1 = none  (float, in [0, 0.5])"), std::string::npos);
}

TEST(Registry, DefaultsAreTheEmbeddedDefaultCase) {
  const ImpactConfig c = load_config(std::nullopt, {});
  const ImpactConfig d;  // the struct's own initializers must agree with the registry
  EXPECT_EQ(c.M, 100.0);
  EXPECT_EQ(c.L, 10.0);
  EXPECT_DOUBLE_EQ(c.lambda_bar, moes_lambda_bar(100.0));
  EXPECT_DOUBLE_EQ(c.alpha_bar, moes_alpha_bar(100.0, 10.0));
  EXPECT_FALSE(c.physical);
  EXPECT_EQ(c.M, d.M);
  EXPECT_EQ(c.L, d.L);
  EXPECT_EQ(c.lubricant.viscosity, d.lubricant.viscosity);
  EXPECT_EQ(c.lubricant.density, d.lubricant.density);
  EXPECT_EQ(c.elastic, d.elastic);
  EXPECT_EQ(c.grid_points, 257);
  EXPECT_EQ(c.grid_points, d.grid_points);
  EXPECT_EQ(c.half_width, d.half_width);
  EXPECT_EQ(c.dT, 0.0);  // the mesh size
  EXPECT_EQ(c.dT, d.dT);
  EXPECT_TRUE(std::isinf(c.T_end));  // until lift-off
  EXPECT_EQ(c.T_end, d.T_end);
  EXPECT_EQ(c.Delta0, d.Delta0);
  EXPECT_EQ(c.V0, d.V0);
  EXPECT_EQ(c.waviness_amplitude, d.waviness_amplitude);
  EXPECT_EQ(c.waviness_wavelength, d.waviness_wavelength);
  EXPECT_EQ(c.waviness_angle_deg, d.waviness_angle_deg);
  EXPECT_EQ(c.cycle, d.cycle);
  EXPECT_EQ(c.tolerance, d.tolerance);
  EXPECT_EQ(c.max_cycles, d.max_cycles);
  EXPECT_EQ(c.pre_sweeps, d.pre_sweeps);
  EXPECT_EQ(c.post_sweeps, d.post_sweeps);
  EXPECT_EQ(c.coarsest_points, d.coarsest_points);
  EXPECT_EQ(c.deformation, d.deformation);
  EXPECT_EQ(c.snapshot_every, d.snapshot_every);
  EXPECT_EQ(c.snapshot_times, d.snapshot_times);
  EXPECT_DOUBLE_EQ(effective_time_step(c), 3.0 / 256.0);
}

TEST(Registry, ReadsATomlFile) {
  TempDir dir;
  const fs::path file = write_file(dir / "case.toml", R"(
# a comment
[case]
M = 20          # an integer is a fine float
[lubricant]
viscosity = "roelands"
density = "dowson-higginson"
eta0 = 0.04
z = 0.6
ph_star = 1.0e9
[body]
elastic = false
[grid]
points = 129.0  # an integral float is a fine integer
half_width = 2
[time]
dT = 0.01
T_end = 4.5
Delta0 = 2
V0 = 0.5
[surface]
waviness_amplitude = 0.1
waviness_wavelength = 0.25
waviness_angle_deg = -30
[output]
snapshot_every = 5
snapshot_times = [3.223, 1, 4.0]
[solver]
cycle = "W"
tolerance = 1e-6
max_cycles = 12
pre_sweeps = 3
post_sweeps = 0
coarsest_points = 9
deformation = "direct"
)");
  const ImpactConfig c = load_config(file, {});
  EXPECT_EQ(c.M, 20.0);
  EXPECT_DOUBLE_EQ(c.lambda_bar, moes_lambda_bar(20.0));
  // The Roelands law's z sets L (Parameters.ARoelandsLawGivenItsOwnAlphaHasItsOwnL).
  EXPECT_DOUBLE_EQ(c.alpha_bar, 0.6 * (std::log(0.04) + 9.67) / 1.96e8 * 1e9);
  EXPECT_DOUBLE_EQ(c.L, moes_L(c.lambda_bar, c.alpha_bar));
  EXPECT_EQ(c.lubricant.viscosity, ViscosityModel::Roelands);
  EXPECT_EQ(c.lubricant.density, DensityModel::DowsonHigginson);
  EXPECT_EQ(c.lubricant.eta0_Pa_s, 0.04);
  EXPECT_EQ(c.lubricant.roelands_z, 0.6);
  EXPECT_EQ(c.lubricant.ph_star_Pa, 1e9);
  EXPECT_FALSE(c.elastic);
  EXPECT_EQ(c.grid_points, 129);
  EXPECT_EQ(c.half_width, 2.0);
  EXPECT_EQ(c.dT, 0.01);
  EXPECT_EQ(c.T_end, 4.5);
  EXPECT_EQ(c.Delta0, 2.0);
  EXPECT_EQ(c.V0, 0.5);
  EXPECT_EQ(c.waviness_amplitude, 0.1);
  EXPECT_EQ(c.waviness_wavelength, 0.25);
  EXPECT_EQ(c.waviness_angle_deg, -30.0);
  EXPECT_EQ(c.snapshot_every, 5);
  EXPECT_EQ(c.snapshot_times, (std::vector<double>{3.223, 1.0, 4.0}));
  EXPECT_EQ(c.cycle, CycleType::W);
  EXPECT_EQ(c.tolerance, 1e-6);
  EXPECT_EQ(c.max_cycles, 12);
  EXPECT_EQ(c.pre_sweeps, 3);
  EXPECT_EQ(c.post_sweeps, 0);
  EXPECT_EQ(c.coarsest_points, 9);
  EXPECT_EQ(c.deformation, DeformationMethod::Direct);
}

TEST(Registry, SetOverridesUseTomlValueSyntax) {
  const ImpactConfig c =
      load_config(std::nullopt,
                  {"case.M=20", "lubricant.viscosity=roelands", "lubricant.eta0=0.04",
                   "lubricant.ph_star=1e9", "body.elastic=false", "output.snapshot_times=[1, 2.5]",
                   "solver.cycle=\"W\"", " grid.points = 65 ", "time.T_end=inf"});
  EXPECT_EQ(c.M, 20.0);
  EXPECT_EQ(c.lubricant.viscosity, ViscosityModel::Roelands);
  EXPECT_FALSE(c.elastic);
  EXPECT_EQ(c.snapshot_times, (std::vector<double>{1.0, 2.5}));
  EXPECT_EQ(c.cycle, CycleType::W);
  EXPECT_EQ(c.grid_points, 65);
  EXPECT_TRUE(std::isinf(c.T_end));
  // A single number is a one-entry array.
  EXPECT_EQ(load_config(std::nullopt, {"output.snapshot_times=3.2"}).snapshot_times,
            std::vector<double>{3.2});
}

TEST(RegistryErrors, AKeyNestedDeeperThanAnyOfEhlsimsIsRefusedBeforeTheParser) {
  // 50 000 parts (100 kB) overflowed the stack of the TOML parser (SIGSEGV),
  // as a key, a table header or a key of an inline table.
  TempDir dir;
  std::string parts = "x";
  for (int i = 0; i < 50000; ++i) parts += ".x";
  std::string part_key = "a";
  for (int i = 0; i < 249; ++i) part_key += ".a";
  std::string nested = "1";
  for (int i = 0; i < 150; ++i) nested = "{" + part_key + " = " + nested + "}";
  // The deep line: 2 for each, 3 after a string whose line ends in a backslash.
  const std::vector<std::pair<std::string, int>> files = {
      {"[case]\n" + parts + " = 1\n", 2},
      {"\n[" + parts + "]\n", 2},
      {"\nv = { " + parts + " = 1 }\n", 2},
      // 150 inline tables, each under a key of 250 parts: each key passed a
      // count of the dots of one key, and the file crashed the parser too.
      {"[case]\nM = " + nested + "\n", 2},
      {"x = \"\"\"a\\\n b\"\"\"\n" + parts + " = 1\n", 3},
      // A multi-line string that ends in quotes ("""q"""" is q") hid the rest of its line.
      {"[case]\nx = { note = \"\"\"q\"\"\"\", " + parts + " = 1 }\n", 2},
      {"[case]\nx = { note = \'\'\'q\'\'\'\'\', " + parts + " = 1 }\n", 2}};
  for (const auto& [text, line] : files) {
    const std::string message = config_error(write_file(dir / "deep.toml", text), {});
    EXPECT_NE(message.find("deep.toml:" + std::to_string(line) +
                           ": keys, tables and values nested more than 256 levels deep"),
              std::string::npos)
        << message.substr(0, 200);
  }
  // Dots in comments, strings and numbers are no keys: such a file reads.
  const std::string dots(1000, '.');
  const fs::path fine =
      write_file(dir / "fine.toml", "[case] # " + dots + "\nM = 20.5 # " + dots + "\n[output]\n" +
                                        "snapshot_times = [0.5, 1.5, 2.5] # \"" + dots + "\n");
  EXPECT_EQ(load_config(fine, {}).M, 20.5);
}

TEST(Registry, SetOverridesTheFileAndTheLastSetWins) {
  TempDir dir;
  const fs::path file = write_file(dir / "case.toml", "[case]\nM = 20\n[grid]\npoints = 65\n");
  const ImpactConfig c = load_config(file, {"case.M=50", "grid.points=33", "grid.points=17"});
  EXPECT_EQ(c.M, 50.0);
  EXPECT_EQ(c.grid_points, 17);
  // An override may bring a value back into range after a bad one.
  EXPECT_EQ(load_config(std::nullopt, {"case.M=-1", "case.M=10"}).M, 10.0);
}

TEST(Registry, LambdaBarAndAlphaBarAreAlternativesToMAndL) {
  const double lambda_bar = moes_lambda_bar(20.0);
  const double alpha_bar = moes_alpha_bar(20.0, 7.0);
  const ImpactConfig a = load_config(std::nullopt, {"case.lambda_bar=" + fmt_double(lambda_bar),
                                                    "case.alpha_bar=" + fmt_double(alpha_bar)});
  EXPECT_NEAR(a.M, 20.0, 1e-12);
  EXPECT_NEAR(a.L, 7.0, 1e-12);
  EXPECT_EQ(a.lambda_bar, lambda_bar);
  EXPECT_EQ(a.alpha_bar, alpha_bar);
  // lambda_bar with the default L: alpha_bar follows from M(lambda_bar) and L.
  const ImpactConfig b = load_config(std::nullopt, {"case.lambda_bar=0.5"});
  EXPECT_NEAR(b.L, 10.0, 1e-14);
  EXPECT_DOUBLE_EQ(b.alpha_bar, moes_alpha_bar(moes_M(0.5), 10.0));
}

// ---------------------------------------------------------------------------
// Validation messages: one line, naming the key, the value and what is allowed
// ---------------------------------------------------------------------------

TEST(RegistryErrors, OutOfRange) {
  EXPECT_EQ(set_error({"case.M=-3"}), "case.M = -3: must be > 0 (--set)");
  EXPECT_EQ(set_error({"case.L=-0.5"}), "case.L = -0.5: must be >= 0 (--set)");
  EXPECT_EQ(set_error({"physical.nu1=0.7"}), "physical.nu1 = 0.7: must be in [0, 0.5] (--set)");
  EXPECT_EQ(set_error({"solver.max_cycles=0"}),
            "solver.max_cycles = 0: must be in [1, 2147483647] (--set)");
  EXPECT_EQ(set_error({"solver.tolerance=0.1"}),
            "solver.tolerance = 0.1: must be in (0, 0.01] (--set)");
  EXPECT_EQ(set_error({"output.snapshot_times=[1.0, -2.0]"}),
            "output.snapshot_times = [1, -2]: every entry must be >= 0 (--set)");
  EXPECT_EQ(set_error({"case.M=nan"}), "case.M = nan: must be a number > 0 (--set)");
  EXPECT_EQ(set_error({"case.M=inf"}), "case.M = inf: must be a finite number > 0 (--set)");
  // The range as the help gives it.
  EXPECT_EQ(set_error({"time.T_end=0"}), "time.T_end = 0: must be > 0 or inf (--set)");
  EXPECT_EQ(set_error({"time.T_end=-inf"}), "time.T_end = -inf: must be > 0 or inf (--set)");
  EXPECT_EQ(set_error({"solver.max_cycles=10000000000"}),
            "solver.max_cycles = 10000000000: must be in [1, 2147483647] (--set)");
}

TEST(RegistryErrors, ANumberTooSmallForADoubleIsNamedAsWritten) {
  // TOML reads 1e-400 as 0, and the message echoed the 0 ("case.M = 0:
  // must be > 0"): a value the user never wrote.
  const std::string too_small =
      ": is too small for a double, which would read it as 0 (the smallest positive double is "
      "4.94066e-324)";
  EXPECT_EQ(set_error({"case.M=1e-400"}), "case.M = 1e-400" + too_small + " (--set)");
  EXPECT_EQ(set_error({"case.L=-2.5E-999"}), "case.L = -2.5E-999" + too_small + " (--set)");
  EXPECT_EQ(set_error({"case.L=0e7"}), "");  // a zero written as one
  // ... and one too large, which TOML refuses to read ("must be a number").
  EXPECT_EQ(
      set_error({"case.M=1e400"}),
      "case.M = 1e400: is beyond the range of a double (magnitudes up to 1.79769e+308) (--set)");
  EXPECT_EQ(set_error({"case.M=1e400x"}), "case.M = \"1e400x\": must be a number > 0 (--set)");
  // An integer beyond 64 bits, which TOML refuses too: it was shown quoted,
  // as if it were text.
  const std::string too_large =
      ": is beyond the range of an integer (magnitudes up to 9223372036854775807; a larger number "
      "is written with an exponent, such as 1e30) (--set)";
  EXPECT_EQ(set_error({"grid.points=99999999999999999999"}),
            "grid.points = 99999999999999999999" + too_large);
  EXPECT_EQ(set_error({"case.L=-9223372036854775809"}),
            "case.L = -9223372036854775809" + too_large);
  EXPECT_EQ(set_error({"case.L=-9223372036854775808"}),
            "case.L = -9223372036854775808: must be >= 0 (--set)");
  // ... in hexadecimal, octal or binary, with '_' between digits, or as an
  // element of an array (shown quoted before, as if it were text).
  EXPECT_EQ(set_error({"case.M=0xFFFFFFFFFFFFFFFFFF"}),
            "case.M = 0xFFFFFFFFFFFFFFFFFF" + too_large);
  EXPECT_EQ(set_error({"time.max_steps=0x8000000000000000"}),
            "time.max_steps = 0x8000000000000000" + too_large);
  EXPECT_EQ(set_error({"time.max_steps=0x7FFF_FFFF_FFFF_FFFF"}),
            "time.max_steps = 9223372036854775807: must be in [1, 10000000] (--set)");
  EXPECT_EQ(set_error({"time.max_steps=1_000_000_000_000_000_000_000"}),
            "time.max_steps = 1_000_000_000_000_000_000_000" + too_large);
  EXPECT_EQ(set_error({"output.snapshot_times=[1, 0o7777777777777777777777]"}),
            "output.snapshot_times = [1, 0o7777777777777777777777]: 0o7777777777777777777777 " +
                too_large.substr(2));
  EXPECT_EQ(set_error({"output.snapshot_times=[1,99999999999999999999 ]"}),
            "output.snapshot_times = [1,99999999999999999999 ]: 99999999999999999999 " +
                too_large.substr(2));
  EXPECT_EQ(set_error({"grid.points=0099"}),
            "grid.points = \"0099\": must be an integer 2^k + 1 "
            "between 9 and 4097 (--set)");
  TempDir dir;
  const fs::path file = write_file(dir / "tiny.toml",
                                   "[time]\nT_end = 1.0 # a run\n[output]\nsnapshot_times = "
                                   "[0.5, 1e-400]\n");
  EXPECT_EQ(config_error(file, {}),
            "output.snapshot_times = 1e-400" + too_small + " (" + file.string() + ":4:24)");
}

TEST(RegistryErrors, GridPointsMustBeTwoToTheKPlusOne) {
  for (const char* bad : {"100", "5", "8193", "0", "-257"}) {
    EXPECT_EQ(set_error({std::string("grid.points=") + bad}),
              std::string("grid.points = ") + bad + ": must be 2^k + 1 between 9 and 4097 (--set)");
  }
  for (const int good : {9, 17, 33, 4097}) {
    EXPECT_EQ(load_config(std::nullopt,
                          {"grid.points=" + std::to_string(good), "solver.coarsest_points=5"})
                  .grid_points,
              good);
  }
  EXPECT_EQ(set_error({"solver.coarsest_points=12"}),
            "solver.coarsest_points = 12: must be 2^k + 1 between 5 and 4097 (--set)");
  EXPECT_EQ(set_error({"grid.points=33", "solver.coarsest_points=65"}),
            "solver.coarsest_points = 65: must be <= grid.points (33) (--set)");
  // The default coarsest level (17) comes down to a 9-point grid; a given one does not.
  EXPECT_EQ(load_config(std::nullopt, {"grid.points=9"}).coarsest_points, 9);
  EXPECT_EQ(load_config(std::nullopt, {"grid.points=33"}).coarsest_points, 17);
  EXPECT_EQ(set_error({"grid.points=9", "solver.coarsest_points=17"}),
            "solver.coarsest_points = 17: must be <= grid.points (9) (--set)");
}

TEST(RegistryErrors, WrongType) {
  EXPECT_EQ(set_error({"case.M=abc"}), "case.M = \"abc\": must be a number > 0 (--set)");
  EXPECT_EQ(set_error({"case.M=\"20\""}), "case.M = \"20\": must be a number > 0 (--set)");
  EXPECT_EQ(set_error({"body.elastic=3"}), "body.elastic = 3: must be true or false (--set)");
  EXPECT_EQ(set_error({"body.elastic=False"}),
            "body.elastic = \"False\": must be true or false (--set)");
  EXPECT_EQ(set_error({"grid.points=2.5"}),
            "grid.points = 2.5: must be an integer 2^k + 1 between 9 and 4097 (--set)");
  EXPECT_EQ(set_error({"output.snapshot_every=true"}),
            "output.snapshot_every = true: must be an integer in [1, 2147483647] (--set)");
  EXPECT_EQ(set_error({"lubricant.viscosity=sae30"}),
            "lubricant.viscosity = \"sae30\": must be one of \"barus\", \"roelands\" (--set)");
  EXPECT_EQ(set_error({"solver.cycle=F"}),
            "solver.cycle = \"F\": must be one of \"V\", \"W\" (--set)");
  EXPECT_EQ(set_error({"output.snapshot_times=[1, \"x\"]"}),
            "output.snapshot_times = [1, \"x\"]: must be an array of numbers >= 0 (--set)");
}

TEST(RegistryErrors, UnknownKeysAndSections) {
  EXPECT_EQ(set_error({"case.Mx=3"}),
            "unknown key 'case.Mx' (known keys in [case]: M, L, lambda_bar, alpha_bar) (--set)");
  EXPECT_EQ(set_error({"grid.point=33"}),
            "unknown key 'grid.point' (known keys in [grid]: points, half_width) (--set)");
  const std::string sections =
      "known sections: case, physical, lubricant, body, grid, time, surface, output, solver, spike";
  EXPECT_EQ(set_error({"cases.M=3"}),
            "unknown key 'cases.M' (unknown section [cases]; " + sections + ") (--set)");
  EXPECT_EQ(set_error({"M=3"}), "unknown key 'M' (keys belong to a section: " +
                                    sections.substr(std::string("known sections: ").size()) +
                                    "; write [section] or section.key) (--set)");
  EXPECT_EQ(set_error({"case.M"}), "--set 'case.M': expected KEY=VALUE, e.g. --set case.M=20");
  EXPECT_EQ(set_error({"=3"}), "--set '=3': expected KEY=VALUE, e.g. --set case.M=20");

  TempDir dir;
  const std::string f = (dir / "bad.toml").string();
  write_file(f, "[case]\nM = 20\n\n[cse]\nL = 3\n");
  EXPECT_EQ(config_error(f, {}),
            "unknown key 'cse.L' (unknown section [cse]; " + sections + ") (" + f + ":5:5)");
  write_file(f, "[case]\nM = 20\n[empty]\n");
  EXPECT_EQ(config_error(f, {}), "unknown section '[empty]' (" + sections + ") (" + f + ":3:1)");
  // An empty known section: an empty [physical] ran the default case.
  write_file(f, "[physical]\n");
  EXPECT_EQ(config_error(f, {}),
            "section [physical] is empty: give its keys (known keys: reduced_radius, ball_radius, "
            "ball_mass, ball_density, impact_speed, reduced_modulus, E1, nu1, E2, nu2, eta0, "
            "alpha, rho0) or leave it out (" +
                f + ":1:1)");
  write_file(f, "case = 3\n");
  EXPECT_EQ(config_error(f, {}), "case = 3: must be a table (section [case]) (" + f + ":1:8)");
  write_file(f, "[grid]\npoints = 100\n");
  EXPECT_EQ(config_error(f, {}),
            "grid.points = 100: must be 2^k + 1 between 9 and 4097 (" + f + ":2:10)");
}

TEST(RegistryErrors, UnreadableAndMalformedFiles) {
  EXPECT_EQ(config_error(fs::path("/nonexistent/x.toml"), {}),
            "cannot read config file '/nonexistent/x.toml': No such file or directory");
  TempDir dir;
  EXPECT_EQ(config_error(dir.path(), {}),
            "cannot read config file '" + dir.path().string() + "': is a directory");
  const std::string f = (dir / "malformed.toml").string();
  write_file(f, "[case]\nM = \n");
  const std::string message = config_error(f, {});
  EXPECT_EQ(message.rfind(f + ":2:", 0), 0u) << message;
  EXPECT_EQ(message.find('\n'), std::string::npos);
  write_file(f, "[case]\nM = 1\nM = 2\n");
  EXPECT_EQ(config_error(f, {}).rfind(f + ":3:", 0), 0u) << config_error(f, {});
  // An endless or huge input is refused after its first 16 MiB, not read into memory.
  constexpr std::size_t kLimit = std::size_t{16} << 20;
  const std::string too_large = ": larger than 16777216 bytes, not a case file";
  EXPECT_EQ(config_error(fs::path("/dev/zero"), {}),
            "cannot read config file '/dev/zero'" + too_large);
  write_file(f, "# " + std::string(kLimit, 'x') + "\n[case]\nM = 20\n");
  EXPECT_EQ(config_error(f, {}), "cannot read config file '" + f + "'" + too_large);
  write_file(f, "# " + std::string(kLimit - 20, 'x') + "\n[case]\nM = 20\n");
  EXPECT_EQ(load_config(fs::path(f), {}).M, 20.0);  // just below the limit: read
}

TEST(RegistryErrors, AConfigFileUnreadableForLackOfDescriptorsIsTheMachinesFailure) {
  // Out of descriptors the file is not at fault: SystemFailure (exit 1), not
  // ConfigError (exit 2, "bad input").  The soft limit is set to the lowest
  // free descriptor, so that the next open fails with EMFILE.
  TempDir dir;
  const fs::path f = write_file(dir / "case.toml", "[case]\nM = 20\n");
  rlimit saved{};
  ASSERT_EQ(getrlimit(RLIMIT_NOFILE, &saved), 0);
  const int lowest_free = ::open("/dev/null", O_RDONLY);
  ASSERT_GE(lowest_free, 0);
  ::close(lowest_free);
  rlimit tight = saved;
  tight.rlim_cur = static_cast<rlim_t>(lowest_free);
  ASSERT_EQ(setrlimit(RLIMIT_NOFILE, &tight), 0);
  std::string what;
  bool system_failure = false;
  try {
    (void)load_config(f, {});
  } catch (const SystemFailure& e) {
    system_failure = true;
    what = e.what();
  } catch (const std::exception& e) {
    what = e.what();
  }
  ASSERT_EQ(setrlimit(RLIMIT_NOFILE, &saved), 0);
  EXPECT_TRUE(system_failure) << what;
  EXPECT_EQ(what, "cannot read config file '" + f.string() + "': Too many open files");
  EXPECT_EQ(load_config(f, {}).M, 20.0);  // with descriptors to spare: read
  // So is an I/O error: /proc/self/mem reads with EIO at its first byte.
  EXPECT_THROW(
      {
        try {
          (void)load_config(fs::path("/proc/self/mem"), {});
        } catch (const SystemFailure& e) {
          EXPECT_STREQ(e.what(), "cannot read config file '/proc/self/mem': Input/output error");
          throw;
        }
      },
      SystemFailure);
}

TEST(Parameters, ARoelandsLawGivenItsOwnAlphaHasItsOwnL) {
  // lubricant.alpha = 2e-8 with ph* = 1 GPa: alpha_bar = 20 at p = 0, so L is
  // Moes' L of alpha_bar 20 at M = 100, as in the rolling contact; run.json
  // recorded the default L = 10 and its alpha_bar 16.9 before.
  const std::vector<std::string> roelands = {"lubricant.viscosity=roelands", "lubricant.eta0=0.05",
                                             "lubricant.ph_star=1e9"};
  std::vector<std::string> with_alpha = roelands;
  with_alpha.push_back("lubricant.alpha=2e-8");
  const ImpactConfig c = load_config(std::nullopt, with_alpha);
  EXPECT_NEAR(c.alpha_bar, 20.0, 1e-12);
  EXPECT_NEAR(c.L, moes_L(c.lambda_bar, 20.0), 1e-12);
  EXPECT_NEAR(c.lubricant.roelands_z, Lubricant::roelands_z_from_alpha(2e-8, 0.05), 1e-15);
  // z derived from case.L (neither z nor alpha given) keeps case.L.
  EXPECT_EQ(load_config(std::nullopt, roelands).L, 10.0);
  // Both is a contradiction, in a file too (examples/roelands-dh.toml gives L).
  std::vector<std::string> with_alpha_bar = with_alpha;
  with_alpha_bar.push_back("case.alpha_bar=3");
  EXPECT_EQ(set_error(with_alpha_bar),
            "case.alpha_bar = 3: cannot be given together with lubricant.alpha: the Roelands "
            "law's pressure-viscosity coefficient sets L and alpha_bar (give one of them) (--set)");
  const fs::path example = source_dir() / "examples" / "roelands-dh.toml";
  EXPECT_EQ(config_error(example, {"lubricant.z=0.6"}),
            "case.L = 10: cannot be given together with lubricant.z: the Roelands law's "
            "pressure-viscosity coefficient sets L and alpha_bar (give one of them) (" +
                example.string() + ":17:5)");
  // A [physical] section's alpha sets z: a z beside it contradicted it.
  EXPECT_EQ(set_error({"physical.reduced_radius=0.01", "physical.ball_mass=0.03",
                       "physical.impact_speed=0.1", "physical.reduced_modulus=2.2e11",
                       "physical.eta0=0.04", "physical.alpha=2e-8", "lubricant.viscosity=roelands",
                       "lubricant.z=0.6"}),
            "lubricant.z = 0.6: is set by physical.alpha of the [physical] section; remove one "
            "(--set)");
}

TEST(RegistryErrors, InconsistentCombinations) {
  EXPECT_EQ(
      set_error({"case.M=20", "case.lambda_bar=0.5"}),
      "case.lambda_bar = 0.5: cannot be given together with case.M (give one of them) (--set)");
  EXPECT_EQ(set_error({"case.L=2", "case.alpha_bar=5"}),
            "case.alpha_bar = 5: cannot be given together with case.L (give one of them) (--set)");
  EXPECT_EQ(
      set_error({"solver.pre_sweeps=0", "solver.post_sweeps=0"}),
      "solver.post_sweeps = 0: solver.pre_sweeps + solver.post_sweeps must be >= 1 (they are 0 "
      "and 0) (--set)");
  // An input the chosen law ignores is refused (it was silently ignored).
  EXPECT_EQ(set_error({"lubricant.z=0.6"}),
            "lubricant.z = 0.6: is used only by lubricant.viscosity = \"roelands\" (the law is "
            "\"barus\") (--set)");
  EXPECT_EQ(set_error({"lubricant.eta0=0.04"}),
            "lubricant.eta0 = 0.04: is used only by lubricant.viscosity = \"roelands\" (the law is "
            "\"barus\") (--set)");
  // ... and so is ph*, which only the Roelands and Dowson-Higginson laws use.
  EXPECT_EQ(
      set_error({"lubricant.ph_star=1e9"}),
      "lubricant.ph_star = 1000000000: is used only by lubricant.viscosity = \"roelands\" and "
      "lubricant.density = \"dowson-higginson\" (the laws are \"barus\" and "
      "\"incompressible\") (--set)");
  // A Roelands index that is not finite (ph* = 1e-300 Pa: the run diverged).
  EXPECT_EQ(set_error({"lubricant.viscosity=roelands", "lubricant.eta0=0.04",
                       "lubricant.ph_star=1e-300"}),
            "lubricant.ph_star = 1e-300: gives a Roelands index z = alpha p0 / (ln(eta0) + 9.67) "
            "that is not finite (alpha = 1.69127e+301 1/Pa) (--set)");
  // One cycle must end in reasonable time: a signal is acted on between cycles.
  EXPECT_EQ(set_error({"solver.pre_sweeps=2000000000"}),
            "solver.pre_sweeps = 2000000000: must be in [0, 20] (--set)");
  EXPECT_EQ(set_error({"solver.post_sweeps=21"}),
            "solver.post_sweeps = 21: must be in [0, 20] (--set)");
  EXPECT_EQ(set_error({"time.V0=1e300"}), "time.V0 = 1e+300: must be in [1e-06, 1e+06] (--set)");
  // 1e308 degrees overflowed in radians: a NaN film even at amplitude 0, or
  // the wavelength blamed with a NaN bound.
  EXPECT_EQ(set_error({"surface.waviness_angle_deg=1e308"}),
            "surface.waviness_angle_deg = 1e+308: must be in [-360, 360] (--set)");
  EXPECT_NO_THROW(load_config(std::nullopt, {"surface.waviness_angle_deg=-360"}));
  // A mesh wider than the dry contact cannot resolve it (1e300: "too viscous" at T = 0).
  EXPECT_EQ(set_error({"grid.half_width=1e300", "time.dT=0.01"}).substr(0, 52),
            "grid.half_width = 1e+300: gives a mesh of 7.813e+297");
  // A profile resampled ever finer grew without bound (1e-7: 12 GB in 18 s).
  EXPECT_EQ(set_error({"spike.resample_meshes=1e-7"}),
            "spike.resample_meshes = 1e-07: must be in [0.01, 1] (--set)");
  EXPECT_EQ(set_error({"lubricant.viscosity=roelands"}),
            "lubricant.ph_star is required by lubricant.viscosity = \"roelands\" (reference Hertz "
            "pressure [Pa]; or give a [physical] section)");
  EXPECT_EQ(set_error({"lubricant.density=dowson-higginson"}),
            "lubricant.ph_star is required by lubricant.density = \"dowson-higginson\" (reference "
            "Hertz pressure [Pa]; or give a [physical] section)");
  EXPECT_EQ(
      set_error({"lubricant.viscosity=roelands", "lubricant.ph_star=1e9"}),
      "lubricant.eta0 is required by lubricant.viscosity = \"roelands\" (ambient viscosity [Pa "
      "s]; or give a [physical] section)");
  EXPECT_EQ(
      set_error({"lubricant.viscosity=roelands", "lubricant.ph_star=1e9", "lubricant.eta0=1e-5"}),
      "lubricant.eta0 = 1e-05: must be > 6.31499e-05 Pa s for the Roelands law (ln(eta0) + "
      "9.67 > 0) (--set)");
  EXPECT_EQ(
      set_error({"lubricant.viscosity=roelands", "lubricant.ph_star=1e9", "lubricant.eta0=0.04",
                 "lubricant.z=0.6", "lubricant.alpha=2e-8"}),
      "lubricant.alpha = 2e-08: give either lubricant.z or lubricant.alpha, not both (--set)");
}

// ---------------------------------------------------------------------------
// Physical cases
// ---------------------------------------------------------------------------

constexpr const char* kSteelBall = R"([physical]
ball_radius = 0.01      # m
ball_density = 7850.0   # kg/m^3
impact_speed = 0.1      # m/s
E1 = 210e9
nu1 = 0.3
E2 = 210e9
nu2 = 0.3
eta0 = 0.04             # Pa s
alpha = 2e-8            # 1/Pa
rho0 = 870.0
)";

TEST(Physical, ComputesMoesParametersAndScales) {
  TempDir dir;
  const fs::path file = write_file(dir / "steel.toml", kSteelBall);
  const ImpactConfig c = load_config(file, {});
  ASSERT_TRUE(c.physical);
  const PhysicalCase p = ehlsim::testing::steel_ball();
  const MoesGroups g = moes_groups(p);
  EXPECT_DOUBLE_EQ(c.M, g.M);
  EXPECT_DOUBLE_EQ(c.L, g.L);
  EXPECT_DOUBLE_EQ(c.lambda_bar, g.lambda_bar);
  EXPECT_DOUBLE_EQ(c.alpha_bar, g.alpha_bar);
  EXPECT_DOUBLE_EQ(c.physical->ph_star_Pa, p.ph_star_Pa);
  EXPECT_DOUBLE_EQ(c.physical->delta_star_m, p.delta_star_m);
  EXPECT_DOUBLE_EQ(c.physical->a_star_m, p.a_star_m);
  EXPECT_DOUBLE_EQ(c.physical->t_bar_s, p.t_bar_s);
  EXPECT_EQ(c.physical->rho0_kg_m3, 870.0);
  EXPECT_DOUBLE_EQ(c.lubricant.ph_star_Pa, p.ph_star_Pa);

  // The same case with the reduced inputs.
  const ImpactConfig r = load_config(
      std::nullopt,
      {"physical.reduced_radius=0.01", "physical.ball_mass=" + fmt_double(p.mass_kg),
       "physical.impact_speed=0.1", "physical.reduced_modulus=" + fmt_double(p.reduced_modulus_Pa),
       "physical.eta0=0.04", "physical.alpha=2e-8"});
  EXPECT_DOUBLE_EQ(r.M, c.M);
  EXPECT_DOUBLE_EQ(r.L, c.L);

  // Roelands takes eta0, alpha and ph* from [physical].
  const ImpactConfig roelands = load_config(file, {"lubricant.viscosity=roelands"});
  EXPECT_EQ(roelands.lubricant.eta0_Pa_s, 0.04);
  EXPECT_DOUBLE_EQ(roelands.lubricant.roelands_z, Lubricant::roelands_z_from_alpha(2e-8, 0.04));
  EXPECT_DOUBLE_EQ(roelands.lubricant.ph_star_Pa, p.ph_star_Pa);
}

TEST(Physical, ErrorsNameTheKey) {
  TempDir dir;
  const std::string f = write_file(dir / "steel.toml", kSteelBall).string();
  EXPECT_EQ(config_error(f, {"case.M=20"}),
            "case.M = 20: cannot be combined with a [physical] section (M, L, lambda_bar and "
            "alpha_bar are computed from it) (--set)");
  EXPECT_EQ(config_error(f, {"physical.reduced_radius=0.01"}),
            "physical.reduced_radius = 0.01: give either physical.ball_radius or "
            "physical.reduced_radius, not both (--set)");
  EXPECT_EQ(config_error(f, {"physical.reduced_modulus=2e11"}),
            "physical.E1 = 210000000000: give either physical.reduced_modulus or E1, nu1, E2, nu2, "
            "not both (" +
                f + ":5:6)");
  EXPECT_EQ(
      config_error(f, {"lubricant.ph_star=1e9"}),
      "lubricant.ph_star = 1000000000: is given by the [physical] section; remove one of them "
      "(--set)");
  EXPECT_EQ(set_error({"physical.ball_radius=0.01"}),
            "physical.ball_mass (or physical.ball_density) is required with a [physical] section");
  EXPECT_EQ(set_error({"physical.ball_radius=0.01", "physical.ball_mass=0.03"}),
            "physical.impact_speed is required with a [physical] section");
  EXPECT_EQ(
      set_error({"physical.ball_radius=0.01", "physical.ball_mass=0.03", "physical.impact_speed=1",
                 "physical.E1=2e11"}),
      "physical.nu1 is required with a [physical] section (or give physical.reduced_modulus)");
  EXPECT_EQ(
      set_error({"physical.rho0=870"}),
      "physical.ball_radius (or physical.reduced_radius) is required with a [physical] section");
}

TEST(Examples, AllExamplesLoad) {
  const fs::path examples = source_dir() / "examples";
  // default.toml: the built-in defaults plus the paper's snapshot times.
  const ImpactConfig d = load_config(examples / "default.toml", {});
  EXPECT_EQ(effective_parameters_json(d),
            effective_parameters_json(load_config(
                std::nullopt, {"output.snapshot_times=[2.609, 3.223, 3.574, 4.0, 4.2]"})));
  // physical.toml: the steel ball, M = 82.5, L = 17.1.
  const ImpactConfig p = load_config(examples / "physical.toml", {});
  ASSERT_TRUE(p.physical);
  EXPECT_NEAR(p.M, 82.49, 0.005);
  EXPECT_NEAR(p.L, 17.09, 0.005);
  EXPECT_NEAR(p.physical->ph_star_Pa, 1.355e9, 0.0005e9);
  // roelands-dh.toml: z from alpha = alpha_bar / ph*.
  const ImpactConfig r = load_config(examples / "roelands-dh.toml", {});
  EXPECT_EQ(r.lubricant.viscosity, ViscosityModel::Roelands);
  EXPECT_EQ(r.lubricant.density, DensityModel::DowsonHigginson);
  EXPECT_NEAR(r.lubricant.roelands_z, 0.5138, 0.00005);
  EXPECT_DOUBLE_EQ(r.lubricant.roelands_z,
                   Lubricant::roelands_z_from_alpha(r.alpha_bar / 1e9, 0.04));
}

// ---------------------------------------------------------------------------
// Echo of the effective parameters
// ---------------------------------------------------------------------------

TEST(Echo, EffectiveParametersUseRegistryKeys) {
  TempDir dir;
  const fs::path file = write_file(dir / "steel.toml", kSteelBall);
  for (const ImpactConfig& c :
       {load_config(std::nullopt, {}), load_config(file, {"lubricant.viscosity=roelands"})}) {
    const nlohmann::json j = effective_parameters_json(c);
    for (auto section = j.begin(); section != j.end(); ++section) {
      if (section.key() == "scales") continue;  // derived, not inputs
      for (auto it = section->begin(); it != section->end(); ++it) {
        EXPECT_NE(find_parameter(section.key() + "." + it.key()), nullptr)
            << section.key() << "." << it.key();
      }
    }
    EXPECT_EQ(j["case"]["M"].get<double>(), c.M);
    EXPECT_EQ(j["case"]["lambda_bar"].get<double>(), c.lambda_bar);
    EXPECT_EQ(j["grid"]["points"].get<int>(), c.grid_points);
    EXPECT_TRUE(j["time"]["T_end"].is_null());
    EXPECT_DOUBLE_EQ(j["time"]["dT"].get<double>(), 3.0 / 256.0);
  }
  const nlohmann::json p = effective_parameters_json(load_config(file, {}));
  EXPECT_EQ(p["lubricant"]["viscosity"], "barus");
  EXPECT_NEAR(p["physical"]["reduced_radius"].get<double>(), 0.01, 1e-15);
  EXPECT_GT(p["scales"]["ph_star_Pa"].get<double>(), 1e9);
  EXPECT_EQ(effective_parameters_json(load_config(std::nullopt, {"time.T_end=3"}))["time"]["T_end"],
            3.0);
}

// The impact and the rolling contact read [lubricant] alike, so they echo it
// alike: in run.json and in the case summary a run prints (the rolling
// summary once named only the two laws, not the Roelands law's eta0 and z).
TEST(Echo, BothModesDescribeTheLubricantAlike) {
  const std::vector<std::string> roelands_dh = {"lubricant.viscosity=roelands",
                                                "lubricant.density=dowson-higginson",
                                                "lubricant.eta0=0.04", "lubricant.ph_star=1e9"};
  const ImpactConfig impact = load_config(std::nullopt, roelands_dh);
  const RollingConfig rolling = load_rolling_config(std::nullopt, roelands_dh);
  EXPECT_EQ(effective_parameters_json(impact)["lubricant"],
            rolling_parameters_json(rolling)["lubricant"]);
  EXPECT_EQ(lubricant_json(impact.lubricant)["z"].get<double>(), impact.lubricant.roelands_z);
  EXPECT_EQ(lubricant_text(impact.lubricant), lubricant_text(rolling.lubricant));
  EXPECT_EQ(lubricant_text(impact.lubricant),
            "roelands, dowson-higginson (eta0 = 0.04 Pa s, z = 0.5138), ph* = 1e+09 Pa");
  EXPECT_EQ(lubricant_text(load_config(std::nullopt, {}).lubricant), "barus, incompressible");
}

}  // namespace
}  // namespace ehlsim
