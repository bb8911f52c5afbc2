// sim/present/report.h — `ncosim report DIR`: one self-contained report.html of an output folder
// (inline SVG figures of `ncosim plot` and CSS; no script, no network): summary table with statuses
// highlighted, extra (e.g. paired-comparison) columns, design summary, manifest and scenario
// text, every text escaped. Sweeps get a case index and one collapsible section per case.
// Bad input (no summary.csv) is a ScenarioError; a failing gnuplot a std::runtime_error.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "sim/present/plot.h"
#include "sim/present/report_parts.h"  // html_escape

namespace ncosim::sim {

// An SVG document made embeddable: the XML prolog and DOCTYPE dropped, every id (and every
// reference to one) prefixed with `prefix`, so that several figures share one page.
std::string inline_svg(const std::string& svg, const std::string& prefix);

struct ReportFigure {
  std::string title;
  std::string svg;  // the SVG file's content
};

// The report of `dir` with these figures (reads summary.csv, manifest.json, design.json and the
// scenario file named in the manifest, where they exist).
std::string build_report(const std::string& dir, const std::vector<ReportFigure>& figures);

struct ReportOptions {
  PlotOptions plot;     // metric etc. of the figures (formats: svg)
  std::string out;      // default DIR/report.html
  bool figures = true;  // false: no gnuplot, no figures (tables only)
};

// `ncosim report`: renders the figures (SVG) into DIR, writes the report, prints the times.
int report_command(const std::string& dir, const ReportOptions& opt);

}  // namespace ncosim::sim
