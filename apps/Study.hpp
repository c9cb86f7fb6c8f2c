#pragma once
// `ehlsim study`: the pressure-spike study of the paper with one command
// (apps/Study.cpp).
#include <CLI/CLI.hpp>
#include <string>
#include <vector>

struct StudyOptions {
  int grid = 257;
  int rolling_grid = 257;  ///< points per side of the rolling runs (similarity figure)
  std::string out_dir = "study";
  int jobs = 2;
  std::vector<std::string> overrides;
  bool no_plots = false;
  std::string python = "/usr/bin/python3";
  std::string plot_script;  ///< "" = scripts/plot_study.py of the source tree
};

CLI::App* add_study_command(CLI::App& app, StudyOptions& options);
int run_study(const StudyOptions& options);
