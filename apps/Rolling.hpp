#pragma once
// `ehlsim rolling`: one steady rolling point contact (apps/Rolling.cpp).
#include <CLI/CLI.hpp>
#include <string>
#include <vector>

struct RollingOptions {
  std::string config_file;  ///< "" = the built-in default case
  std::string out_dir = "rolling";
  std::vector<std::string> overrides;
  bool quiet = false;
};

CLI::App* add_rolling_command(CLI::App& app, RollingOptions& options);
int run_rolling(const RollingOptions& options);
