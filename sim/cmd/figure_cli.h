// sim/cmd/figure_cli.h — the `plot` and `report` subcommands' options (hooked into sim/cmd/cli.cc).
#pragma once

#include <CLI/CLI.hpp>
#include <optional>
#include <string>

#include "sim/present/plot.h"
#include "sim/present/report.h"

namespace ncosim::sim {

struct FigureCommands {
  CLI::App* plot = nullptr;
  CLI::App* report = nullptr;
  std::string dir;
  std::string formats = "png,svg";
  PlotOptions plot_options;
  ReportOptions report_options;
  bool no_figures = false;
};

void add_figure_commands(CLI::App& app, FigureCommands& fc);

// The exit status of the parsed command, or nullopt when neither was given.
std::optional<int> run_figure_commands(FigureCommands& fc);

}  // namespace ncosim::sim
