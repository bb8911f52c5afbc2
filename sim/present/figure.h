// sim/present/figure.h — one figure of `ncosim plot` (its kind, options and files) and the gnuplot
// text every figure builder shares (sim/present/plot.cc, plot_trace.cc, plot_curve.cc): the script
// around a figure's body, series colours, quoted strings, and the fields and titles read from an
// output folder.
#pragma once

#include <cstddef>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace ncosim::sim {

enum class FigureKind {
  kPerEstimator,  // one case: metric per estimator, CI bars, prediction beside
  kAgainstKey,    // one sweep key (or all but the panel key fixed): metric against the key
  kPanels,        // two or more keys: one panel per value of the panel key(s)
  kTrace,         // --trace: run 0's state and estimates against time
};
const char* figure_kind_name(FigureKind k);

struct PlotOptions {
  std::string metric = "mse";  // a numeric column of summary.csv
  std::string x_key;  // sweep key on the x axis (default: the first numeric key, else the first)
  std::string panel_key;      // sweep key of the panels (default: every other key together)
  std::string logx = "auto";  // auto | on | off
  std::string logy = "auto";
  std::vector<std::string> formats{"png", "svg"};
  bool trace = false;        // also the trace figure from trajectory.csv
  long trace_from = 0;       // first period of the trace window
  long trace_periods = 200;  // periods in the trace window
};

// One figure: its base name (files <name>.dat, <name>.gp, <name>.<format>) and content.
struct Figure {
  std::string name;
  FigureKind kind = FigureKind::kPerEstimator;
  std::string title;
  std::string dat, gp;
};

// The gnuplot script of figure `name` around `body` (one pass per output format), and the line
// colour of the e-th series: shared by every figure of `ncosim plot`.
std::string gnuplot_script(const std::string& name, const std::string& what, int width, int height,
                           const std::string& body);
std::string gnuplot_colour(std::size_t e);

// At most kMostSeries series share a panel (the palette's colours, none repeated); more are split
// into series_groups(n) groups of at most kGroupSeries, one panel each.
inline constexpr std::size_t kMostSeries = 10;
inline constexpr std::size_t kGroupSeries = 8;
inline std::size_t series_groups(std::size_t series) {
  return series <= kMostSeries ? 1 : (series + kGroupSeries - 1) / kGroupSeries;
}

// Quoted gnuplot string literal (single quotes, '' for a quote; line breaks become spaces).
std::string gnuplot_quote(const std::string& s);

// The pieces the figure builders share (a using-directive in their .cc files).
namespace figure_text {

std::string read_file(const std::filesystem::path& p);

std::optional<double> number(const std::string& s);

// The field as written in the CSV, or '?' (gnuplot's missing value) when it is not a number.
std::string dat_field(const std::string& s);

// One-line comment text for a .dat file.
std::string comment(const std::string& s);

std::string scenario_title(const std::string& dir);

std::string tics(const std::vector<std::string>& labels);

}  // namespace figure_text

}  // namespace ncosim::sim
