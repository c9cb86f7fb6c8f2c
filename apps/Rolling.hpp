#pragma once
// `ehlsim rolling`: one steady rolling point contact (apps/Rolling.cpp).
#include <CLI/CLI.hpp>
#include <string>
#include <vector>

#include "Cli.hpp"

struct RollingOptions : cli::CaseOptions {
  RollingOptions() { out_dir = "rolling"; }
};

CLI::App* add_rolling_command(CLI::App& app, RollingOptions& options);
int run_rolling(const RollingOptions& options);
