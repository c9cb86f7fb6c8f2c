#pragma once
// The memory guard's refusal as both modes must give it (docs/usage.md,
// "Memory guard"): `ehlsim <command> --set grid.points=4097 --set
// solver.memory_limit_mb=100 --out OUT` exits 2 at once with one line that
// names grid.points, the estimate and the limit, and prints nothing else.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <string>

#include "support/RunEhlsim.hpp"

namespace ehlsim::testing {

/// Runs the refused command for `mode` ("impact" or "rolling") into `out`.
inline void expect_memory_guard_refusal(const std::string& mode, const std::filesystem::path& out) {
  const auto start = std::chrono::steady_clock::now();
  const Result r = ehlsim(mode + " --set grid.points=4097 --set solver.memory_limit_mb=100 --out " +
                          quote(out.string()));
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.err.rfind("ehlsim: error: grid.points = 4097: the run needs about ", 0), 0u) << r.err;
  EXPECT_NE(r.err.find(" MB of memory (estimate), more than the limit solver.memory_limit_mb = "
                       "100: use fewer grid.points, or raise solver.memory_limit_mb\n"),
            std::string::npos)
      << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;  // one line
  EXPECT_TRUE(r.out.empty()) << r.out;  // refused before the case is printed
  EXPECT_LT(seconds, 10.0);             // before any allocation (milliseconds unloaded)
}

}  // namespace ehlsim::testing
