// tests/sim/table_view_test.cc — the stdout table of `run` (issue 28, part 1): it fits the
// width, long notes become footnotes printed once for the rows that share them, columns are left
// out (and named) by priority, rows never wrap; the column list and format options; the
// expected statuses of part 5 (status_as_expected, status_text, the expected_status column).
#include "sim/present/table_view.h"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <pty.h>
#include <sys/ioctl.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <sstream>

#include "config/config.h"
#include "sim/analysis/output.h"

namespace ncosim::sim {
namespace {

std::size_t code_points(const std::string& s) {
  std::size_t w = 0;
  for (unsigned char ch : s) w += (ch & 0xC0) != 0x80;
  return w;
}

std::vector<std::string> lines_of(const std::string& text) {
  std::vector<std::string> out;
  std::istringstream in(text);
  for (std::string l; std::getline(in, l);) out.push_back(l);
  return out;
}

std::size_t count(const std::string& text, const std::string& what) {
  std::size_t n = 0;
  for (auto at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

// The flagship's shape: 7 rows, five jump rows sharing the model_check reason (~230 characters)
// with their own numbers, a Kalman and an open-loop row without a note.
std::vector<ViewColumn> flagship_like() {
  const std::string why =
      "design model not followed (physical packets on delay links 'net1', 'net2': one copy per "
      "sample, several "
      "possible delays <= max_delay; the design assumes independent copies per delay)";
  std::vector<ViewColumn> cols{
      {"estimator",
       "estimator",
       {"S1, 1 gain", "S2, 2 gains", "S3, 4 gains", "S3, 8 gains", "S4, 60 gains", "Kalman",
        "open loop"},
       0,
       false},
      {"mse", "mse ± 95% CI", {}, 1, false},
      {"mse_ext", "mse_ext ± 95% CI", {}, 3, false},
      {"predicted_mse_ext", "pred. mse_ext", {}, 4, false},
      {"status", "status", {"ok", "ok", "ok", "ok", "ok", "ok", "diverged (expected)"}, 1, false},
      {"mse_diff", "Δmse vs ref ± CI", {}, 5, false},
      {"rmse_x1", "rmse_x1", {}, 8, false},
      {"rmse_x2", "rmse_x2", {}, 8, false},
      {"model_check", "note", {}, 2, true}};
  for (int r = 0; r < 7; ++r) {
    cols[1].cells.push_back("0.03089 ± 0.00031");
    cols[2].cells.push_back("0.04829 ± 0.00046");
    cols[3].cells.push_back(r < 5 ? "0.05993" : "–");
    cols[5].cells.push_back(r < 5 ? "0.006145 ± 0.0019" : "–");
    cols[6].cells.push_back("0.1714");
    cols[7].cells.push_back("0.06273");
    cols[8].cells.push_back(
        r < 5 ? why + ": predicted mse_ext 0.0" + std::to_string(5 + r) + ", simulated 0.04" : "");
  }
  return cols;
}

std::vector<std::string> flagship_labels() {
  return {"\"S1, 1 gain\"",   "\"S2, 2 gains\"", "\"S3, 4 gains\"", "\"S3, 8 gains\"",
          "\"S4, 60 gains\"", "\"Kalman\"",      "\"open loop\""};
}

TEST(TableView, FlagshipLikeTableFits120WithTheSharedNotePrintedOnce) {
  std::vector<std::string> kept;
  const std::string out = fit_table(flagship_like(), flagship_labels(), 120, true, &kept);
  for (const auto& l : lines_of(out)) EXPECT_LE(code_points(l), 120u) << l;
  // One footnote for the five rows: the reason once, each row's numbers under it.
  EXPECT_EQ(count(out, "design model not followed"), 1u) << out;
  EXPECT_EQ(count(out, "| [1]"), 5u) << out;
  EXPECT_EQ(count(out, "[2]"), 0u) << out;
  EXPECT_NE(out.find("\"S4, 60 gains\": predicted mse_ext 0.09, simulated 0.04"), std::string::npos)
      << out;
  EXPECT_NE(out.find("diverged (expected)"), std::string::npos);
  // Left out by priority (the rmse columns first), named by their summary.csv names in one line.
  EXPECT_EQ(std::count(kept.begin(), kept.end(), "rmse_x1"), 0);
  EXPECT_EQ(std::count(kept.begin(), kept.end(), "status"), 1);
  EXPECT_EQ(std::count(kept.begin(), kept.end(), "model_check"), 1);
  EXPECT_NE(out.find("Left out to fit 120 columns: "), std::string::npos) << out;
  EXPECT_NE(out.find("rmse_x1, rmse_x2 (`--columns`"), std::string::npos) << out;
}

TEST(TableView, NothingLeftOutWhenItFits) {
  std::vector<ViewColumn> cols{{"estimator", "estimator", {"a", "b"}, 0, false},
                               {"status", "status", {"ok", "ok"}, 1, false}};
  const std::string out = fit_table(cols, {"a", "b"}, 120, true);
  EXPECT_EQ(out,
            "| estimator | status |\n|-----------|--------|\n| a         | ok     |\n| b         | "
            "ok     |\n");
}

TEST(TableView, ManySweepKeysLeaveOutLowerPrioritiesAndNeverWrap) {
  // Eight sweep keys of 16 characters: the identity alone is 153 wide, wider than 120. Every
  // other column goes, the rows stay whole (one line each), and the line says what went.
  std::vector<ViewColumn> cols;
  for (int k = 0; k < 8; ++k)
    cols.push_back({fmt::format("link[{}].delivery", k),
                    fmt::format("link[{}].delivery", k),
                    {"0.5", "0.9"},
                    0,
                    false});
  cols.push_back({"estimator", "estimator", {"kf", "jump"}, 0, false});
  cols.push_back({"mse", "mse ± 95% CI", {"1 ± 0.1", "2 ± 0.2"}, 1, false});
  cols.push_back({"status", "status", {"ok", "ok"}, 1, false});
  std::vector<std::string> kept;
  const std::string out = fit_table(cols, {"r1", "r2"}, 120, true, &kept);
  const auto lines = lines_of(out);
  ASSERT_GE(lines.size(), 4u);
  EXPECT_EQ(lines[2].rfind("| 0.5", 0), 0u);  // row 1 on one line
  EXPECT_EQ(lines[3].rfind("| 0.9", 0), 0u);  // row 2 on the next
  EXPECT_EQ(kept.size(), 9u);
  EXPECT_NE(out.find("Left out to fit 120 columns: mse, status"), std::string::npos) << out;
}

TEST(TableView, ChosenColumnsAreNeverLeftOutAndLongCellsBecomeFootnotes) {
  const std::string long_status = "design_unstable: p0 rho(A)^2 = 1.7 >= 1 (no stable design)";
  std::vector<ViewColumn> cols{{"estimator", "estimator", {"a", "b", "c"}, 0, false},
                               {"status", "status", {long_status, long_status, "ok"}, 1, false}};
  const std::string out =
      fit_table(cols, {"a", "b", "c"}, 20, false);  // the table is 22 wide: kept whole
  EXPECT_EQ(out.rfind("| estimator | status |\n", 0), 0u) << out;
  EXPECT_EQ(count(out, "[1] design_unstable:"), 1u)
      << out;  // one footnote for both rows, wrapped at 20
  EXPECT_EQ(count(out, "| [1]"), 2u) << out;
  EXPECT_EQ(out.find("Left out"), std::string::npos) << out;
}

TEST(TableView, WrapTextBreaksAtSpacesWithAHangingIndent) {
  EXPECT_EQ(wrap_text("aaa bbb ccc", 7, 2), "aaa bbb\n  ccc\n");
  EXPECT_EQ(wrap_text("short", 80, 4), "short\n");
  EXPECT_EQ(wrap_text("averyveryverylongword x", 5, 1), "averyveryverylongword\n x\n");
}

TEST(TableView, ColumnListAndFormatAreChecked) {
  EXPECT_EQ(parse_column_list("mse, status ,estimator"),
            (std::vector<std::string>{"mse", "status", "estimator"}));
  EXPECT_THROW(parse_column_list("mse,,status"), config::ScenarioError);
  EXPECT_THROW(parse_column_list(""), config::ScenarioError);
  const std::vector<std::string> valid{"estimator", "mse", "status", "expected_status"};
  EXPECT_NO_THROW(check_table_request({{"mse", "status"}, "json"}, valid));
  try {
    check_table_request({{"msee"}, ""}, valid);
    ADD_FAILURE() << "no error";
  } catch (const config::ScenarioError& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("--columns: no summary.csv column \"msee\" (did you mean \"mse\"?)"),
              std::string::npos)
        << m;
    EXPECT_NE(m.find("estimator, mse, status, expected_status"), std::string::npos) << m;
  }
  try {
    check_table_request({{}, "xml"}, valid);
    ADD_FAILURE() << "no error";
  } catch (const config::ScenarioError& e) {
    EXPECT_NE(std::string(e.what()).find("--format: expected md, csv or json, got \"xml\""),
              std::string::npos);
  }
}

// Issue 40.6: the table fitted a fixed 120 columns whatever the terminal (an 80-column terminal
// wrapped every row). COLUMNS first (a positive integer), then the terminal's width, then 120.
TEST(TableView, WidthIsColumnsElseTheTerminalElse120) {
  FILE* file = std::tmpfile();  // not a terminal
  ASSERT_NE(file, nullptr);
  const int plain = ::fileno(file);
  EXPECT_EQ(table_width(nullptr, plain), 120u);
  EXPECT_EQ(table_width("80", plain), 80u);
  EXPECT_EQ(table_width("200", plain), 200u);
  for (const char* bad : {"", "abc", "0", "-5", "80x", " 80"})
    EXPECT_EQ(table_width(bad, plain), 120u) << "COLUMNS=\"" << bad << "\"";
  EXPECT_EQ(table_width("12", plain), kNarrowestTableWidth);
  std::fclose(file);
  int master = -1, slave = -1;
  winsize ws{};
  ws.ws_col = 97;
  ws.ws_row = 30;
  ASSERT_EQ(::openpty(&master, &slave, nullptr, nullptr, &ws), 0);
  EXPECT_EQ(table_width(nullptr, slave), 97u);  // the terminal's width
  EXPECT_EQ(table_width("150", slave), 150u);   // COLUMNS wins
  ::close(master);
  ::close(slave);
}

// The table printed with the default width fits it; with a narrower one, columns are left out
// and every line still fits.
TEST(TableView, FlagshipLikeTableFitsAnyWidthItIsGiven) {
  for (const std::size_t width : {80u, 100u, 160u}) {
    const std::string out = fit_table(flagship_like(), flagship_labels(), width, true);
    for (const auto& l : lines_of(out)) EXPECT_LE(code_points(l), width) << l;
  }
}

// --columns ...,status shows the status as the default table does ("diverged (expected)");
// csv and json keep summary.csv's bare status beside expected_status.
TEST(ExpectedStatus, ChosenStatusColumnSaysExpectedLikeTheTable) {
  SummaryRow a, b;
  a.estimator = "Kalman";
  a.status = "ok";
  b.estimator = "open loop";
  b.status = "diverged";
  b.expected_status = "diverged";
  const std::vector<SummaryRow> rows{a, b};
  const std::string md = summary_markdown("t", {}, rows, 0);
  TableRequest req{{"estimator", "status"}, ""};
  const std::string table = stdout_table(req, "t", {}, rows, 0, md, "");
  EXPECT_NE(table.find("| open loop | diverged (expected) |"), std::string::npos) << table;
  req.format = "md";
  EXPECT_NE(stdout_table(req, "t", {}, rows, 0, md, "").find("diverged (expected)"),
            std::string::npos);
  req.format = "csv";
  const std::string csv = stdout_table(req, "t", {}, rows, 0, md, "");
  EXPECT_NE(csv.find("open loop,diverged\n"), std::string::npos) << csv;
  EXPECT_EQ(csv.find("(expected)"), std::string::npos) << csv;
}

TEST(ExpectedStatus, MatchesTheDeclaredStatusOrOkByDefault) {
  EXPECT_TRUE(status_as_expected("ok", ""));
  EXPECT_FALSE(status_as_expected("diverged", ""));
  EXPECT_TRUE(status_as_expected("diverged", "diverged"));
  EXPECT_FALSE(status_as_expected("ok", "diverged"));
  EXPECT_TRUE(status_as_expected("design_unstable: p0 rho(A)^2 = 2 >= 1", "design_failed"));
  EXPECT_FALSE(status_as_expected("numerical_failure", "design_failed"));
  SummaryRow r;
  r.status = "diverged";
  EXPECT_EQ(status_text(r), "diverged");
  r.expected_status = "diverged";
  EXPECT_EQ(status_text(r), "diverged (expected)");
  r.status = "ok";
  EXPECT_EQ(status_text(r), "ok (expected diverged)");
  r.expected_status = "ok";
  EXPECT_EQ(status_text(r), "ok");
}

// expected_status follows model_check and stop; the filter-consistency columns come after it.
TEST(ExpectedStatus, IsTheLastColumnOfSummaryCsvAfterStop) {
  SummaryRow a, b;
  a.estimator = "a";
  a.status = "ok";
  b.estimator = "b";
  b.status = "diverged";
  b.expected_status = "diverged";
  const std::string csv = summary_csv({}, {a, b}, 1);
  const auto lines = lines_of(csv);
  ASSERT_EQ(lines.size(), 3u);
  const std::string consistency = ",nees,nees_lo,nees_hi,nis,nis_lo,nis_hi,consistency";
  const std::string no_statistic = ",,,,,,,";  // seven empty consistency cells
  EXPECT_TRUE(lines[0].ends_with(",model_check,expected_status" + consistency)) << lines[0];
  EXPECT_TRUE(lines[1].ends_with("," + no_statistic)) << lines[1];  // not declared: empty
  EXPECT_TRUE(lines[2].ends_with(",diverged" + no_statistic)) << lines[2];
  a.stop = b.stop = "target_ci";
  EXPECT_TRUE(lines_of(summary_csv({}, {a, b}, 1))[0].ends_with(
      ",model_check,stop,expected_status" + consistency));
  const auto cols = summary_csv_columns({}, 1, true);
  EXPECT_EQ(cols[cols.size() - 8], "expected_status");
}

}  // namespace
}  // namespace ncosim::sim
