// tests/cli/plot_cli_test.cc — `ncosim plot` and `ncosim report` as a user runs them (gnuplot
// included): a two-key sweep with awkward names (spaces, commas, quotes, <tags>, &, unicode), the
// trace figure, the physical state of a re-centred trajectory, bad input (exit 2), and a
// 20-case x 10-estimator report kept under 1 MB.
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <regex>
#include <set>
#include <sstream>

#include "sim/present/plot.h"
#include "test_util.h"

namespace {

namespace fs = std::filesystem;
const std::string kBinary = NCOSIM_BINARY;
const fs::path kData = fs::path(NCOSIM_SOURCE_DIR) / "tests" / "cli" / "data";

std::string shell_quote(const std::string& s) {
  std::string out = "'";
  for (char c : s) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return out + "'";
}

ncosim::testing::CommandOutcome ncosim_cmd(const std::vector<std::string>& args) {
  std::string cmd = shell_quote(kBinary);
  for (const auto& a : args) cmd += " " + shell_quote(a);
  return ncosim::testing::run_shell(cmd);
}

std::string read_file(const fs::path& p) { return ncosim::testing::read_text(p.string()); }

class PlotCli : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    // A folder name with a space, a quote and unicode: gnuplot runs inside it.
    dir_ = fs::temp_directory_path() / fmt::format("ncosim plot 'test' µ {}", ::getpid());
    fs::remove_all(dir_);
    const auto r = ncosim_cmd({"run", (kData / "plot_names.toml").string(), "--out", dir_.string(),
                               "--trace", "--quiet"});
    ASSERT_EQ(r.code, 0) << r.output;
  }
  static void TearDownTestSuite() { fs::remove_all(dir_); }
  static fs::path dir_;
};
fs::path PlotCli::dir_;

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

// Two keys (link[1].loss numeric: the x axis; link[0].pmf: the panels), 2 estimators: 12 rows,
// each equal to summary.csv's fields for its (panel, estimator, loss), in block order.
TEST_F(PlotCli, SweepWithAwkwardNamesGivesPanelsHoldingSummaryNumbers) {
  const auto r = ncosim_cmd({"plot", dir_.string(), "--trace"});
  ASSERT_EQ(r.code, 0) << r.output;
  for (const char* f : {"plot_mse.dat", "plot_mse.gp", "plot_mse.png", "plot_mse.svg", "trace.dat",
                        "trace.gp", "trace.png", "trace.svg"}) {
    ASSERT_TRUE(fs::exists(dir_ / f)) << f;
    EXPECT_GT(fs::file_size(dir_ / f), 100u) << f;
  }
  EXPECT_NE(r.output.find("panels"), std::string::npos) << r.output;
  const auto s = ncosim::sim::parse_csv(read_file(dir_ / "summary.csv"), "summary.csv");
  const auto rows = dat_rows(read_file(dir_ / "plot_mse.dat"));
  ASSERT_EQ(rows.size(), 12u);
  const int mse = s.column("mse"), ci = s.column("mse_ci95"), pred = s.column("predicted_mse");
  std::size_t i = 0;
  for (const std::string pmf : {"[0.5, 0.3]", "[0.8, 0.1]"}) {
    for (int e = 0; e < 2; ++e) {
      for (const auto& row : s.rows) {
        if (row[1] != pmf ||
            row[2] != (e == 0 ? "jump S2, \"two\" gains" : "Kalman — it's <b>µ</b> & co"))
          continue;
        const auto q = [](const std::string& v) { return v.empty() ? std::string("?") : v; };
        EXPECT_EQ(rows[i], (std::vector<std::string>{row[0], row[mse], q(row[ci]), q(row[pred])}))
            << "row " << i;
        ++i;
      }
    }
  }
  EXPECT_EQ(i, 12u);
  // The script quotes the names for gnuplot (a quote doubled), the image shows them.
  const std::string gp = read_file(dir_ / "plot_mse.gp");
  EXPECT_NE(gp.find("'Kalman — it''s <b>µ</b> & co'"), std::string::npos) << gp;
  EXPECT_NE(read_file(dir_ / "plot_mse.svg").find("jump S2, \"two\" gains"), std::string::npos);
  EXPECT_NE(read_file(dir_ / "plot_mse.svg").find("Kalman — it's &lt;b>µ&lt;/b> &amp; co"),
            std::string::npos);
  // The other key on x, one format only.
  const auto r2 = ncosim_cmd(
      {"plot", dir_.string(), "--x", "link[0].pmf", "--panel", "link[1].loss", "--format", "svg"});
  ASSERT_EQ(r2.code, 0) << r2.output;
  EXPECT_NE(read_file(dir_ / "plot_mse.gp").find("set xlabel 'link[0].pmf'"), std::string::npos);
}

TEST_F(PlotCli, BadInputIsExit2NamingTheOption) {
  struct Case {
    std::vector<std::string> args;
    std::string says;
  };
  const std::vector<Case> cases{
      {{"plot", (dir_ / "nope").string()}, "not a directory"},
      {{"plot", dir_.string(), "--metric", "nope"}, "--metric 'nope'"},
      {{"plot", dir_.string(), "--x", "nope"}, "--x 'nope'"},
      {{"plot", dir_.string(), "--format", "gif"}, "--format 'gif'"},
      {{"plot", dir_.string(), "--logy", "maybe"}, "--logy"},
      {{"report", fs::temp_directory_path().string()}, "summary.csv"},
  };
  for (const auto& c : cases) {
    const auto r = ncosim_cmd(c.args);
    EXPECT_EQ(r.code, 2) << c.args[1] << " " << r.output;
    EXPECT_NE(r.output.find(c.says), std::string::npos) << r.output;
  }
}

// The plant A = [[1.02, 0.1], [0, 0.7]] is unstable, so the run is re-centred. The physical state
// satisfies x_p[k] = A x_p[k-1] + x[k] (x: the re-centred state = the part driven by u and w),
// x_p[0] = x[0]; checked on every row to the 9 printed digits.
TEST_F(PlotCli, RecentredTrajectoryCarriesThePhysicalState) {
  const auto man = nlohmann::json::parse(read_file(dir_ / "manifest.json"));
  ASSERT_TRUE(man["recentred"].get<bool>());
  const auto t = ncosim::sim::parse_csv(read_file(dir_ / "trajectory.csv"), "trajectory.csv");
  const int x1 = t.column("x1"), x2 = t.column("x2"), p1 = t.column("x1_physical"),
            p2 = t.column("x2_physical");
  ASSERT_GE(p1, 0);
  ASSERT_GE(p2, 0);
  ASSERT_EQ(t.rows.size(), 300u);
  double prev1 = 0, prev2 = 0, grown = 0;
  for (std::size_t k = 0; k < t.rows.size(); ++k) {
    const auto& r = t.rows[k];
    const double x[2] = {std::stod(r[x1]), std::stod(r[x2])};
    const double p[2] = {std::stod(r[p1]), std::stod(r[p2])};
    const double e1 = k == 0 ? x[0] : 1.02 * prev1 + 0.1 * prev2 + x[0];
    const double e2 = k == 0 ? x[1] : 0.7 * prev2 + x[1];
    EXPECT_NEAR(p[0], e1, 1e-7 * (1 + std::fabs(e1))) << "k = " << k;
    EXPECT_NEAR(p[1], e2, 1e-7 * (1 + std::fabs(e2))) << "k = " << k;
    prev1 = p[0];
    prev2 = p[1];
    grown = std::max(grown, std::fabs(p[0] - x[0]));
  }
  EXPECT_GT(grown, 1.0);  // the physical motion differs from the re-centred one
  // The trace figure says it shows physical coordinates.
  ASSERT_EQ(ncosim_cmd({"plot", dir_.string(), "--trace", "--format", "svg"}).code, 0);
  EXPECT_NE(read_file(dir_ / "trace.dat").find("physical coordinates"), std::string::npos);
}

std::set<std::string> duplicate_ids(const std::string& html) {
  std::set<std::string> seen, dup;
  const std::regex id(R"re(\sid=["']([^"']*)["'])re");
  for (auto it = std::sregex_iterator(html.begin(), html.end(), id); it != std::sregex_iterator();
       ++it) {
    if (!seen.insert((*it)[1].str()).second) dup.insert((*it)[1].str());
  }
  return dup;
}

TEST_F(PlotCli, ReportIsSelfContainedWellFormedAndEscaped) {
  const auto r = ncosim_cmd({"report", dir_.string()});
  ASSERT_EQ(r.code, 0) << r.output;
  const fs::path html_path = dir_ / "report.html";
  const std::string html = read_file(html_path);
  EXPECT_LT(html.size(), 1'000'000u);
  EXPECT_EQ(html.find("<script"), std::string::npos);
  EXPECT_EQ(html.find("src="), std::string::npos);  // nothing loaded from elsewhere
  EXPECT_EQ(html.find("<link"), std::string::npos);
  EXPECT_NE(html.find("Kalman — it&#39;s &lt;b&gt;µ&lt;/b&gt; &amp; co"), std::string::npos);
  EXPECT_EQ(html.find("<b>µ</b>"), std::string::npos);
  std::size_t figures = 0;
  for (auto p = html.find("<figure"); p != std::string::npos; p = html.find("<figure", p + 1))
    ++figures;
  EXPECT_EQ(figures, 4u);  // mse, mse_ext, paired mse_diff, trace
  EXPECT_TRUE(duplicate_ids(html).empty());
  const auto lint =
      ncosim::testing::run_shell("xmllint --noout " + shell_quote(html_path.string()));
  EXPECT_EQ(lint.code, 0) << lint.output;
}

// 20 cases x 10 estimators: a case index and one collapsible section per case, under 1 MB.
TEST(ReportCli, TwentyCaseTenEstimatorSweepStaysUnderOneMegabyte) {
  std::string sc = read_file(kData / "base.toml");
  const auto pos = sc.find("[[estimator]]");
  ASSERT_NE(pos, std::string::npos);
  sc = sc.substr(0, pos);
  const char* groupings[] = {"S1", "S2", "S3", "S4"};
  for (int e = 0; e < 8; ++e) {
    sc += fmt::format(
        "[[estimator]]\nname = \"jump {} N={}\"\nkind = \"jump\"\ngrouping = \"{}\"\nhistory = "
        "{}\nmax_delay = 1\n\n",
        groupings[e % 4], 1 + e / 4, groupings[e % 4], 1 + e / 4);
  }
  sc += "[[estimator]]\nname = \"Kalman\"\nkind = \"kalman_extended\"\nmax_delay = 1\n\n";
  sc += "[[estimator]]\nname = \"open loop\"\nkind = \"open_loop\"\nmax_delay = 1\n\n";
  sc += "[[sweep]]\nkey = \"link[1].loss\"\nvalues = [";
  for (int c = 0; c < 20; ++c) sc += fmt::format("{}{:.2f}", c ? ", " : "", 0.02 + 0.04 * c);
  sc += "]\n";
  const fs::path d = fs::temp_directory_path() / fmt::format("ncosim_report_20x10_{}", ::getpid());
  fs::remove_all(d);
  fs::create_directories(d);
  {
    std::ofstream o(d / "sweep.toml");
    o << sc;
  }
  const auto run = ncosim_cmd({"run", (d / "sweep.toml").string(), "--out", (d / "out").string(),
                               "--runs", "2", "--periods", "200", "--quiet"});
  ASSERT_EQ(run.code, 0) << run.output;
  const auto r = ncosim_cmd({"report", (d / "out").string()});
  ASSERT_EQ(r.code, 0) << r.output;
  const std::string html = read_file(d / "out" / "report.html");
  EXPECT_LT(html.size(), 1'000'000u);
  std::cout << "20 x 10 report: " << html.size() << " bytes; " << r.output;
  for (int c = 1; c <= 20; ++c)
    EXPECT_NE(html.find(fmt::format("<details id=\"case-{}\">", c)), std::string::npos) << c;
  EXPECT_NE(html.find("href=\"#case-20\""), std::string::npos);
  EXPECT_TRUE(duplicate_ids(html).empty());
  fs::remove_all(d);
}

}  // namespace
