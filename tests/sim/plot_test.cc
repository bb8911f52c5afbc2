// tests/sim/plot_test.cc — `ncosim plot` without gnuplot: the CSV reader, the figure kind chosen
// for each campaign shape, the .dat files holding summary.csv's numbers as written, the quoting
// of awkward names in the scripts, and the report's escaping and SVG id prefixing.
#include "sim/present/plot.h"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "config/config.h"
#include "sim/present/report.h"

namespace {

namespace fs = std::filesystem;
using ncosim::sim::CsvTable;
using ncosim::sim::FigureKind;
using ncosim::sim::PlotOptions;

const char* kHead = "estimator,kind,runs,mse,mse_ci95,predicted_mse,status\n";

fs::path temp_dir(const std::string& name) {
  const fs::path d =
      fs::temp_directory_path() / ("ncosim_plot_test_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

void write(const fs::path& p, const std::string& s) {
  std::ofstream o(p, std::ios::binary);
  o << s;
}

TEST(ParseCsv, QuotedFieldsKeepCommasQuotesAndLineBreaks) {
  const CsvTable t =
      ncosim::sim::parse_csv("a,b\r\n\"x, \"\"y\"\"\",\"line\nbreak\"\n,\n", "t.csv");
  ASSERT_EQ(t.rows.size(), 2u);
  EXPECT_EQ(t.rows[0][0], "x, \"y\"");
  EXPECT_EQ(t.rows[0][1], "line\nbreak");
  EXPECT_EQ(t.rows[1][0], "");
  EXPECT_EQ(t.column("b"), 1);
  EXPECT_EQ(t.column("c"), -1);
}

TEST(ParseCsv, MalformedInputNamesFileAndLine) {
  try {
    ncosim::sim::parse_csv("a,b\n1,2\n3\n", "t.csv");
    FAIL() << "no error";
  } catch (const ncosim::config::ScenarioError& e) {
    EXPECT_NE(std::string(e.what()).find("t.csv:3"), std::string::npos) << e.what();
  }
  EXPECT_THROW(ncosim::sim::parse_csv("a\n\"open\n", "t.csv"), ncosim::config::ScenarioError);
}

// One case -> per estimator; one key -> against the key; two keys -> panels (or, with the second
// key as the x key and the first as panels, still panels); options naming no key are errors.
TEST(PlotKind, FollowsTheCampaignShape) {
  PlotOptions o;
  const auto one = ncosim::sim::parse_csv(std::string(kHead) + "a,jump,2,1,0.1,,ok\n", "s");
  EXPECT_EQ(ncosim::sim::summary_figure_kind(one, o), FigureKind::kPerEstimator);
  const auto swept = ncosim::sim::parse_csv(
      std::string("k,") + kHead + "1,a,jump,2,1,0.1,,ok\n2,a,jump,2,1,0.1,,ok\n", "s");
  EXPECT_EQ(ncosim::sim::summary_figure_kind(swept, o), FigureKind::kAgainstKey);
  const auto two = ncosim::sim::parse_csv(
      std::string("k,m,") + kHead + "1,x,a,jump,2,1,0.1,,ok\n2,y,a,jump,2,1,0.1,,ok\n", "s");
  EXPECT_EQ(ncosim::sim::summary_figure_kind(two, o), FigureKind::kPanels);
  o.x_key = "m";
  o.panel_key = "k";
  EXPECT_EQ(ncosim::sim::summary_figure_kind(two, o), FigureKind::kPanels);
  o.panel_key = "m";
  EXPECT_THROW(ncosim::sim::summary_figure_kind(two, o),
               ncosim::config::ScenarioError);  // x = panel
  o.x_key = "nope";
  o.panel_key.clear();
  EXPECT_THROW(ncosim::sim::summary_figure_kind(two, o), ncosim::config::ScenarioError);
  o.x_key = "k";
  EXPECT_THROW(ncosim::sim::summary_figure_kind(one, o),
               ncosim::config::ScenarioError);  // no sweep key
}

// The data rows of a .dat file (comments and blank lines dropped), split on blanks.
std::vector<std::vector<std::string>> dat_rows(const std::string& dat) {
  std::vector<std::vector<std::string>> rows;
  std::istringstream in(dat);
  for (std::string line; std::getline(in, line);) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream ls(line);
    std::vector<std::string> f;
    for (std::string w; ls >> w;) f.push_back(w);
    rows.push_back(f);
  }
  return rows;
}

// Numbers are copied as written (1.23457e-05 stays 1.23457e-05, 0.100000 stays 0.100000); empty
// cells become gnuplot's missing value '?'; names with quotes, commas and unicode are quoted for
// gnuplot (a quote doubled) and never split into words in the data.
TEST(PlotData, HoldsSummaryNumbersAsWritten) {
  const fs::path d = temp_dir("one");
  write(d / "summary.csv", std::string(kHead) +
                               "\"S1, 1 \"\"gain\"\"\",jump,20,1.23457e-05,0.100000,2.5e-05,ok\n"
                               "Kalman µ's,kalman_extended,20,0.0289304,,,diverged\n");
  const auto figs = ncosim::sim::build_figures(d.string(), PlotOptions{});
  ASSERT_EQ(figs.size(), 1u);
  EXPECT_EQ(figs[0].kind, FigureKind::kPerEstimator);
  const auto rows = dat_rows(figs[0].dat);
  ASSERT_EQ(rows.size(), 2u);
  EXPECT_EQ(rows[0], (std::vector<std::string>{"0", "1.23457e-05", "0.100000", "2.5e-05"}));
  EXPECT_EQ(rows[1], (std::vector<std::string>{"1", "0.0289304", "?", "?"}));
  EXPECT_NE(figs[0].gp.find("'S1, 1 \"gain\"'"), std::string::npos) << figs[0].gp;
  EXPECT_NE(figs[0].gp.find("'Kalman µ''s'"), std::string::npos) << figs[0].gp;
  EXPECT_EQ(ncosim::sim::gnuplot_quote("a'b\nc"), "'a''b c'");
  fs::remove_all(d);
}

// Two keys: one block per (panel, estimator) in file order; a categorical x key is the index of
// its value; the metric, CI and prediction columns as written.
TEST(PlotData, PanelsHoldEveryCaseInBlocks) {
  const fs::path d = temp_dir("panels");
  write(d / "summary.csv",
        std::string("loss,preset,") + kHead +
            "0.1,\"a, b\",e1,jump,4,1.5,0.25,1.4,ok\n0.1,\"a, b\",e2,jump,4,2.5,0.5,,ok\n"
            "0.3,\"a, b\",e1,jump,4,3.5,0.75,3.4,ok\n0.3,\"a, b\",e2,jump,4,4.5,1.5,,ok\n"
            "0.1,c,e1,jump,4,5.5,0.1,,ok\n0.1,c,e2,jump,4,6.5,0.2,,ok\n"
            "0.3,c,e1,jump,4,7.5,0.3,,ok\n0.3,c,e2,jump,4,8.5,0.4,,ok\n");
  const auto figs = ncosim::sim::build_figures(d.string(), PlotOptions{});
  ASSERT_EQ(figs.size(), 1u);
  EXPECT_EQ(figs[0].kind, FigureKind::kPanels);
  EXPECT_NE(figs[0].gp.find("set xlabel 'loss'"), std::string::npos);  // the numeric key is x
  EXPECT_NE(figs[0].gp.find("'preset = a, b'"), std::string::npos);
  const auto rows = dat_rows(figs[0].dat);
  ASSERT_EQ(rows.size(), 8u);
  EXPECT_EQ(rows[0], (std::vector<std::string>{"0.1", "1.5", "0.25", "1.4"}));  // panel "a, b", e1
  EXPECT_EQ(rows[1], (std::vector<std::string>{"0.3", "3.5", "0.75", "3.4"}));
  EXPECT_EQ(rows[2], (std::vector<std::string>{"0.1", "2.5", "0.5", "?"}));  // panel "a, b", e2
  EXPECT_EQ(rows[7], (std::vector<std::string>{"0.3", "8.5", "0.4", "?"}));  // panel c, e2
  // Categorical x: the preset on x, panels per loss.
  PlotOptions o;
  o.x_key = "preset";
  const auto f2 = ncosim::sim::build_figures(d.string(), o);
  const auto r2 = dat_rows(f2[0].dat);
  EXPECT_EQ(r2[0], (std::vector<std::string>{"0", "1.5", "0.25", "1.4"}));
  EXPECT_EQ(r2[1], (std::vector<std::string>{"1", "5.5", "0.1", "?"}));
  EXPECT_NE(f2[0].gp.find("('a, b' 0, 'c' 1)"), std::string::npos) << f2[0].gp;
  o.metric = "no_such_column";
  EXPECT_THROW(ncosim::sim::build_figures(d.string(), o), ncosim::config::ScenarioError);
  fs::remove_all(d);
}

// Paired columns (issue 14): a second figure `plot_mse_diff` holds each row's `mse_diff` and its
// CI as written, on a linear axis with a zero line (even when the differences span a factor of
// 100), and the reference row is labelled as such; the `plot_mse` figure is unchanged.
TEST(PlotData, PairedDifferencesAreASecondFigure) {
  const fs::path d = temp_dir("paired");
  const std::string head =
      "estimator,kind,runs,mse,mse_ci95,predicted_mse,status,paired_reference,mse_diff,mse_diff_"
      "ci95\n";
  write(d / "summary.csv", head +
                               "Kalman,kalman_extended,20,0.03,0.001,,ok,Kalman,,\n"
                               "S1,jump,20,0.08,0.003,0.1,ok,Kalman,0.05,0.002\n"
                               "S4,jump,20,0.0305,0.001,0.04,ok,Kalman,0.0005,0.0008\n");
  const auto figs = ncosim::sim::build_figures(d.string(), PlotOptions{});
  ASSERT_EQ(figs.size(), 2u);
  EXPECT_EQ(figs[0].name, "plot_mse");
  EXPECT_EQ(figs[1].name, "plot_mse_diff");
  EXPECT_EQ(figs[1].kind, FigureKind::kPerEstimator);
  const auto rows = dat_rows(figs[1].dat);
  ASSERT_EQ(rows.size(), 3u);
  EXPECT_EQ(rows[0], (std::vector<std::string>{"0", "?", "?", "?"}));
  EXPECT_EQ(rows[1], (std::vector<std::string>{"1", "0.05", "0.002", "?"}));
  EXPECT_EQ(rows[2], (std::vector<std::string>{"2", "0.0005", "0.0008", "?"}));
  EXPECT_NE(figs[1].gp.find("set xzeroaxis"), std::string::npos) << figs[1].gp;
  EXPECT_EQ(figs[1].gp.find("set logscale"), std::string::npos) << figs[1].gp;
  EXPECT_NE(figs[1].gp.find("'Kalman (reference)'"), std::string::npos) << figs[1].gp;
  EXPECT_NE(figs[1].title.find("reference (Kalman)"), std::string::npos) << figs[1].title;
  EXPECT_EQ(figs[0].gp.find("set xzeroaxis"), std::string::npos);
  // No value in the diff column (e.g. one run): no second figure.
  write(d / "summary.csv",
        head + "Kalman,kalman_extended,1,0.03,,,ok,Kalman,,\nS1,jump,1,0.08,,,ok,Kalman,,\n");
  EXPECT_EQ(ncosim::sim::build_figures(d.string(), PlotOptions{}).size(), 1u);
  fs::remove_all(d);
}

TEST(PlotData, LogAxisOnlyWhenTheRangeAsksForIt) {
  const fs::path d = temp_dir("log");
  write(d / "summary.csv",
        std::string(kHead) + "a,jump,2,0.02,0.001,,ok\nb,open_loop,2,1.3e7,2e5,,ok\n");
  EXPECT_NE(ncosim::sim::build_figures(d.string(), PlotOptions{})[0].gp.find("set logscale y"),
            std::string::npos);
  write(d / "summary.csv",
        std::string(kHead) + "a,jump,2,0.02,0.001,,ok\nb,open_loop,2,0.05,0.002,,ok\n");
  EXPECT_EQ(ncosim::sim::build_figures(d.string(), PlotOptions{})[0].gp.find("set logscale y"),
            std::string::npos);
  PlotOptions on;
  on.logy = "on";
  EXPECT_NE(ncosim::sim::build_figures(d.string(), on)[0].gp.find("set logscale y"),
            std::string::npos);
  fs::remove_all(d);
}

// The `lc rgb` colours of the line series (not the bands) of each `plot` command of a script.
std::vector<std::vector<std::string>> plot_colours(const std::string& gp) {
  std::vector<std::vector<std::string>> out;
  std::istringstream in(gp);
  for (std::string line; std::getline(in, line);) {
    if (line.find("  plot ") == 0) out.emplace_back();
    if (out.empty() || line.find("filledcurves") != std::string::npos) continue;
    const auto at = line.find("lc rgb '");
    if (at != std::string::npos) out.back().push_back(line.substr(at + 8, 7));
  }
  return out;
}

bool all_distinct(std::vector<std::string> v) {
  std::sort(v.begin(), v.end());
  return std::adjacent_find(v.begin(), v.end()) == v.end();
}

// Issue 40.8: 32 rows of one case made a 3770-px-wide figure (110 px per row along x). Above 12
// rows the estimators go down the y axis: 900 px wide, 22 px per row, labels horizontal.
TEST(PlotLayout, ManyRowsOfOneCaseAreADotPlot) {
  const fs::path d = temp_dir("many");
  std::string csv = kHead;
  for (int e = 0; e < 32; ++e) {
    csv += e == 1 ? "optimal N=1,kalman_buffer,2,,,,diverged\n"
                  : fmt::format("row {},static_buffer,2,{},0.5,{},ok\n", e, 20 + e, 19 + e);
  }
  write(d / "summary.csv", csv);
  const auto figs = ncosim::sim::build_figures(d.string(), PlotOptions{});
  ASSERT_EQ(figs.size(), 1u);
  const std::string& gp = figs[0].gp;
  EXPECT_NE(gp.find("size 900,894 "), std::string::npos) << gp;  // 32 x 22 + 190
  EXPECT_NE(gp.find("set ytics ('row 0' 0, 'optimal N=1 (no mse)' 1, "), std::string::npos) << gp;
  EXPECT_NE(gp.find("with xerrorbars"), std::string::npos) << gp;
  EXPECT_NE(gp.find("set xlabel 'mse  (bars: 95 % CI)'"), std::string::npos) << gp;
  EXPECT_EQ(dat_rows(figs[0].dat).size(), 32u);
  EXPECT_EQ(dat_rows(figs[0].dat)[2], (std::vector<std::string>{"2", "22", "0.5", "21"}));
  // 12 rows stay along x.
  csv = kHead;
  for (int e = 0; e < 12; ++e) csv += fmt::format("row {},jump,2,{},0.5,,ok\n", e, 20 + e);
  write(d / "summary.csv", csv);
  EXPECT_EQ(ncosim::sim::build_figures(d.string(), PlotOptions{})[0].gp.find("xerrorbars"),
            std::string::npos);
  fs::remove_all(d);
}

// Issue 40.8: against a key, 32 estimators shared one panel and 10 colours (each colour three
// times). More than 10 are split into groups of at most 8, one panel each, on one y range, and no
// colour repeats within a panel.
TEST(PlotLayout, ManyEstimatorsAgainstAKeyAreSplitIntoPanels) {
  const fs::path d = temp_dir("groups");
  std::string csv = std::string("loss,") + kHead;
  for (const char* loss : {"0.1", "0.2"}) {
    for (int e = 0; e < 20; ++e) csv += fmt::format("{},e{},jump,2,{},0.5,,ok\n", loss, e, 1 + e);
  }
  write(d / "summary.csv", csv);
  const auto figs = ncosim::sim::build_figures(d.string(), PlotOptions{});
  ASSERT_EQ(figs.size(), 1u);
  const std::string& gp = figs[0].gp;
  EXPECT_NE(gp.find("set multiplot layout 2,2"), std::string::npos) << gp;  // 3 groups
  for (const char* t :
       {"'estimators 1–6 of 20'", "'estimators 7–13 of 20'", "'estimators 14–20 of 20'"})
    EXPECT_NE(gp.find(t), std::string::npos) << t << "\n" << gp;
  const auto colours = plot_colours(gp);
  ASSERT_EQ(colours.size(), 3u) << gp;
  for (const auto& panel : colours) {
    EXPECT_LE(panel.size(), 8u);
    EXPECT_TRUE(all_distinct(panel)) << gp;
  }
  EXPECT_NE(gp.find("set yrange ["), std::string::npos) << gp;  // one range for the panels
  fs::remove_all(d);
}

// Issue 40.8: one diverged row's error curve (1e+140) flattened every other curve to the axis,
// and the curve of every period of every estimator made a 6.5 MB report. A diverged row's curve
// is left out of its panel's y range (said in its legend entry), at most 400 periods are drawn
// per curve, and 12 estimators make two panels of 6 with distinct colours.
TEST(PlotLayout, ErrorCurveLeavesADivergedRowOutOfTheScale) {
  const fs::path d = temp_dir("curve");
  std::string curve = "estimator,period,time,runs,mse,mse_ci95\n", summary = kHead;
  for (int e = 0; e < 12; ++e) {
    const std::string name = e == 2 ? "blown" : fmt::format("e{}", e);
    summary +=
        fmt::format("{},jump,3,{},,,{}\n", name, e == 2 ? "" : "5", e == 2 ? "diverged" : "ok");
    for (int k = 0; k < 2000; ++k) {
      const double v = e == 2 ? std::pow(10.0, std::min(140.0, 0.1 * k)) : 1.0 + e + (k % 7);
      curve += fmt::format("{},{},{},3,{},{}\n", name, k, k, v, 0.1 * v);
    }
  }
  write(d / "error_curve.csv", curve);
  write(d / "summary.csv", summary);
  const auto f = ncosim::sim::error_curve_figure(d.string());
  ASSERT_TRUE(f.has_value());
  EXPECT_NE(f->gp.find("set multiplot layout 2,1"), std::string::npos) << f->gp;
  EXPECT_NE(f->gp.find("'estimators 1–6 of 12'"), std::string::npos) << f->gp;
  EXPECT_NE(f->gp.find("'blown (diverged, off the scale)'"), std::string::npos) << f->gp;
  // The first panel's range is its other curves': 1..12 with their bands, not 1e140.
  const auto at = f->gp.find("set yrange [");
  ASSERT_NE(at, std::string::npos) << f->gp;
  const double hi = std::stod(f->gp.substr(f->gp.find(':', at) + 1));
  EXPECT_LT(hi, 100.0) << f->gp.substr(at, 40);
  EXPECT_NE(f->gp.find("set autoscale y"), std::string::npos);  // the second panel has none
  for (const auto& panel : plot_colours(f->gp)) {
    EXPECT_EQ(panel.size(), 6u);
    EXPECT_TRUE(all_distinct(panel)) << f->gp;
  }
  // 2000 periods: one in 5 and the last, 401 points per curve.
  EXPECT_EQ(dat_rows(f->dat).size(), 12u * 401u);
  EXPECT_NE(f->dat.find("one period in 5 and the last"), std::string::npos);
  fs::remove_all(d);
}

TEST(Report, EscapesTextAndPrefixesSvgIds) {
  EXPECT_EQ(ncosim::sim::html_escape("<b>\"a\" & 'b'</b>"),
            "&lt;b&gt;&quot;a&quot; &amp; &#39;b&#39;&lt;/b&gt;");
  const std::string svg =
      "<?xml version=\"1.0\"?>\n<!DOCTYPE svg>\n<svg><g id=\"gnuplot_canvas\"><path id='gpPt0'/>"
      "<use xlink:href='#gpPt0'/><rect fill=\"url(#grad)\"/></g></svg>";
  EXPECT_EQ(ncosim::sim::inline_svg(svg, "f2-"),
            "<svg><g id=\"f2-gnuplot_canvas\"><path id='f2-gpPt0'/><use xlink:href='#f2-gpPt0'/>"
            "<rect fill=\"url(#f2-grad)\"/></g></svg>");
  // Ids repeated inside one SVG (gnuplot's multiplot panels) get a suffix.
  EXPECT_EQ(ncosim::sim::inline_svg("<svg><g id='p'/><g id='p'/><g id=\"p\"/></svg>", "x-"),
            "<svg><g id='x-p'/><g id='x-p-1'/><g id=\"x-p-2\"/></svg>");
}

TEST(Report, SweepGetsCaseSectionsAndHighlightsStatus) {
  const fs::path d = temp_dir("report");
  write(d / "summary.csv", std::string("k,") + kHead +
                               "1,<a>,jump,2,1,0.1,,ok\n1,b,jump,2,2,0.1,,diverged\n"
                               "2,<a>,jump,2,3,0.1,,ok\n2,b,jump,2,4,0.1,,ok\n");
  const std::string h = ncosim::sim::build_report(d.string(), {});
  EXPECT_NE(h.find("id=\"case-1\""), std::string::npos);
  EXPECT_NE(h.find("id=\"case-2\""), std::string::npos);
  EXPECT_NE(h.find("<details"), std::string::npos);
  EXPECT_NE(h.find("&lt;a&gt;"), std::string::npos);
  EXPECT_EQ(h.find("<a>"), std::string::npos);
  EXPECT_NE(h.find("<b>diverged</b>"), std::string::npos);  // listed among the warnings
  EXPECT_EQ(h.find("<script"), std::string::npos);
  fs::remove_all(d);
}

}  // namespace
