// tests/cli/report_cli_test.cc — `ncosim report` is the campaign's (issue 28, part 6): the scenario
// text the campaign ran (from runs.sqlite) and whether the file on disk still holds it, the older
// folder without a store, no mention of a trajectory.csv the run did not write; and neither
// `plot` nor `report` lets gnuplot warn about an empty series (a diverged open-loop row, a
// diverged estimate in the trace window).
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "sim/present/plot.h"
#include "test_util.h"

namespace {

namespace fs = std::filesystem;
using ncosim::testing::run_ncosim;

std::string read_file(const fs::path& p) { return ncosim::testing::read_text(p.string()); }

void write_file(const fs::path& p, const std::string& text) {
  std::ofstream out(p, std::ios::binary | std::ios::trunc);
  out << text;
}

// A scalar plant with A = 1.5 over 2000 periods: the open-loop estimate overflows to inf (status
// diverged, mse empty in every case); the Kalman filter stays finite. Re-centred (unstable).
const std::string kDiverging = R"(title = "diverging open loop"
[run]
periods = 2000
runs = 2
seed = 3

[plant]
kind = "lti"
A  = [[1.5]]
Bu = [[1.0]]
Bw = [[1.0]]
W  = [[1.0]]

[input]
kind = "white"
std = 1.0

[[sensor]]
name = "y"
C = [[1.0]]
R = [[0.01]]
link = "net"

[[link]]
name = "net"
kind = "bernoulli"
loss = 0.9

[[estimator]]
name = "open loop"
kind = "open_loop"

[[estimator]]
name = "kalman"
kind = "kalman_extended"
max_delay = 0

[[sweep]]
key = "link[0].loss"
values = [0.0, 0.9]
)";

class CampaignReport : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           fmt::format("ncosim_report_cli_{}_{}", ::getpid(),
                       ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    scenario_ = dir_ / "diverging.toml";
    write_file(scenario_, kDiverging);
  }
  void TearDown() override { fs::remove_all(dir_); }

  // Runs the scenario into `out` (with `extra` options); asserts success.
  void run(const fs::path& out, const std::vector<std::string>& extra = {}) {
    std::vector<std::string> args{"run", scenario_.string(), "--out", out.string(), "--quiet"};
    args.insert(args.end(), extra.begin(), extra.end());
    const auto r = run_ncosim(args);
    ASSERT_EQ(r.code, 0) << r.output;
  }

  // The report's sentence about the scenario file on disk.
  static std::string disk_sentence(const fs::path& out) {
    const std::string html = read_file(out / "report.html");
    const auto a = html.find("id=\"scenario-disk\">");
    if (a == std::string::npos) return "";
    return html.substr(a + 19, html.find("</p>", a) - a - 19);
  }

  fs::path dir_, scenario_;
};

// Before: "Skipping data file with no valid points" on stderr of both commands (the open-loop
// row's mse is empty in every case; in periods 1900.. its estimate is inf).
TEST_F(CampaignReport, DivergedRowsAndEstimatesReachNoGnuplotWarning) {
  const fs::path out = dir_ / "out";
  run(out, {"--trace"});
  const auto s = ncosim::sim::parse_csv(read_file(out / "summary.csv"), "summary.csv");
  ASSERT_EQ(s.rows.size(), 4u);
  EXPECT_EQ(s.rows[0][static_cast<std::size_t>(s.column("status"))], "diverged");
  EXPECT_EQ(s.rows[0][static_cast<std::size_t>(s.column("mse"))], "");

  const auto plot =
      run_ncosim({"plot", out.string(), "--trace", "--from", "1900", "--format", "svg"});
  ASSERT_EQ(plot.code, 0) << plot.output;
  EXPECT_EQ(plot.output.find("warning"), std::string::npos) << plot.output;
  EXPECT_EQ(plot.output.find("gnuplot"), std::string::npos) << plot.output;
  // The figure says why the row is not drawn; the trace says the estimate diverged.
  EXPECT_NE(read_file(out / "plot_mse.gp").find("'open loop: no finite mse: diverged'"),
            std::string::npos);
  EXPECT_NE(read_file(out / "plot_mse.svg").find("open loop: no finite mse: diverged"),
            std::string::npos);
  EXPECT_NE(read_file(out / "trace.svg").find("open loop: no finite value (diverged)"),
            std::string::npos);

  const auto report = run_ncosim({"report", out.string()});
  ASSERT_EQ(report.code, 0) << report.output;
  EXPECT_EQ(report.output.find("warning"), std::string::npos) << report.output;
  EXPECT_EQ(report.output.find("gnuplot "), std::string::npos)
      << report.output;  // "s gnuplot" timing only
}

// The stored text is shown; the sentence follows the file on disk: unchanged, changed (the edit
// not shown), gone; without runs.sqlite the file as read now, saying so.
TEST_F(CampaignReport, ShowsTheScenarioTheCampaignRanAndWhetherTheFileChanged) {
  const fs::path out = dir_ / "out";
  run(out);
  const auto report = [&] {
    const auto r = run_ncosim({"report", out.string(), "--no-figures"});
    EXPECT_EQ(r.code, 0) << r.output;
  };
  report();
  EXPECT_NE(disk_sentence(out).find("is unchanged since the campaign ran"), std::string::npos)
      << disk_sentence(out);
  EXPECT_NE(
      read_file(out / "report.html").find("The scenario text the campaign ran, from runs.sqlite"),
      std::string::npos);

  write_file(scenario_, kDiverging + "# edited after the run\n");
  report();
  EXPECT_NE(disk_sentence(out).find("has changed since the campaign ran"), std::string::npos)
      << disk_sentence(out);
  EXPECT_EQ(read_file(out / "report.html").find("edited after the run"), std::string::npos);
  EXPECT_NE(read_file(out / "report.html").find("title = &quot;diverging open loop&quot;"),
            std::string::npos);

  fs::remove(scenario_);
  report();
  EXPECT_NE(disk_sentence(out).find("is no longer there"), std::string::npos) << disk_sentence(out);
  EXPECT_NE(read_file(out / "report.html").find("title = &quot;diverging open loop&quot;"),
            std::string::npos);

  // An older folder: no store; the file as read now, and the report says it may differ.
  write_file(scenario_, kDiverging);
  fs::remove(out / "runs.sqlite");
  report();
  EXPECT_NE(disk_sentence(out).find("No run store (runs.sqlite) in this folder"), std::string::npos)
      << disk_sentence(out);
  EXPECT_NE(disk_sentence(out).find("may differ from the text the campaign ran"),
            std::string::npos);
}

// Issue 40.6: the banner listed an `expected` divergence among the rows "not trustworthy". A
// status the scenario declares (expected_status) is listed apart, as expected; a row whose status
// differs from the declared one (here the Kalman filter declared to diverge) is still a warning.
TEST_F(CampaignReport, BannerTreatsAnExpectedStatusAsExpected) {
  const fs::path declared = dir_ / "declared", wrong = dir_ / "wrong";
  run(declared, {"--set", "estimator[0].expected_status=\"diverged\""});
  run(wrong, {"--set", "estimator[0].expected_status=\"diverged\"", "--set",
              "estimator[1].expected_status=\"diverged\""});
  for (const auto& d : {declared, wrong})
    ASSERT_EQ(run_ncosim({"report", d.string(), "--no-figures"}).code, 0);
  const std::string h = read_file(declared / "report.html");
  EXPECT_EQ(h.find("not trustworthy"), std::string::npos) << h.substr(0, 3000);
  EXPECT_NE(h.find("Every row has status ok or the status its scenario expects"),
            std::string::npos);
  EXPECT_NE(h.find("id=\"expected\""), std::string::npos);
  EXPECT_NE(h.find("link[0].loss = 0.0 · open loop: <b>diverged (expected)</b>"), std::string::npos)
      << h.substr(0, 3000);
  EXPECT_EQ(h.find("<tr class=\"bad\">"), std::string::npos);  // no row shaded as a fault
  EXPECT_NE(h.find("<tr class=\"expected\">"), std::string::npos);
  // The status follows the estimator in the summary table (a wide table's scroll never hides it).
  EXPECT_NE(h.find("<th class=\"t\">estimator</th><th class=\"t\">status</th>"), std::string::npos);
  const std::string w = read_file(wrong / "report.html");
  EXPECT_NE(w.find("not trustworthy"), std::string::npos);
  EXPECT_NE(w.find("kalman: <b>ok (expected diverged)</b>"), std::string::npos)
      << w.substr(0, 3000);
  EXPECT_NE(w.find("open loop: <b>diverged (expected)</b>"), std::string::npos);
}

// A re-centred run without --trace writes no trajectory.csv, and the report does not name it
// (before: "trajectory.csv carries the physical state ..."); with --trace it does.
TEST_F(CampaignReport, NamesTrajectoryCsvOnlyWhenTheRunWroteIt) {
  const fs::path plain = dir_ / "plain", traced = dir_ / "traced";
  run(plain);
  run(traced, {"--trace"});
  ASSERT_FALSE(fs::exists(plain / "trajectory.csv"));
  for (const auto& d : {plain, traced})
    ASSERT_EQ(run_ncosim({"report", d.string(), "--no-figures"}).code, 0);
  const std::string p = read_file(plain / "report.html"), t = read_file(traced / "report.html");
  EXPECT_NE(p.find("simulated re-centred"), std::string::npos);
  EXPECT_EQ(p.find("trajectory.csv"), std::string::npos);
  EXPECT_NE(t.find("trajectory.csv carries the physical state"), std::string::npos);
}

}  // namespace
