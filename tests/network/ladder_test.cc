// tests/network/ladder_test.cc — `ncosim record-link` and `ncosim ladder` on a network scenario
// whose jump design has no design_pmf (issue 40, part 3): the record needs no design law; the
// ladder records every network link, fits, writes ordinary scenario files (the one that ran is
// the file), runs them paired with the network and compares; bad input of every option is exit 2
// with the option named and nothing written; a ladder killed half-way leaves nothing in OUT, and
// the next one removes what it left. Built only with ns-3 (NCOSIM_NS3). Small: 3 runs of 200
// periods of the 802.15.4 star.
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "test_util.h"

namespace {

namespace fs = std::filesystem;
using Outcome = ncosim::testing::CommandOutcome;

const fs::path kSource = NCOSIM_SOURCE_DIR;

Outcome ncosim(const std::vector<std::string>& args, const std::string& env = "") {
  return ncosim::testing::run_shell(env + ncosim::testing::ncosim_command(args));
}

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

class Ladder : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           fmt::format("ncosim_ladder_{}_{}", ::getpid(),
                       ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    // The shipped star without its guessed design_pmf: the jump design needs the law.
    std::istringstream in(slurp(kSource / "scenarios/wsn_star.toml"));
    std::string text;
    for (std::string l; std::getline(in, l);) {
      if (l.rfind("design_pmf", 0) != 0) text += l + "\n";
    }
    scenario_ = (dir_ / "star.toml").string();
    std::ofstream(scenario_) << text;
  }
  void TearDown() override { fs::remove_all(dir_); }
  // What the tests share: tiny campaigns, the nodes near the edge of range (some losses).
  std::vector<std::string> ladder(const fs::path& out, std::vector<std::string> more = {}) {
    std::vector<std::string> a{
        "ladder",    scenario_,   "--out",  out.string(), "--runs",
        "3",         "--periods", "200",    "--set",      "network[0].tx_power=-20",
        "--threads", "2",         "--quiet"};
    a.insert(a.end(), more.begin(), more.end());
    return a;
  }
  // The leftovers of a ladder writing `out` beside it (its staging folder).
  static int leftovers(const fs::path& out) {
    int n = 0;
    for (const auto& e : fs::directory_iterator(out.parent_path())) {
      n += e.path().filename().string().rfind("." + out.filename().string() + ".ladder.", 0) == 0;
    }
    return n;
  }
  fs::path dir_;
  std::string scenario_;
};

TEST_F(Ladder, RecordLinkNeedsNoDesignLaw) {
  const Outcome run = ncosim({"run", scenario_, "--out", (dir_ / "run").string(), "--quiet"});
  EXPECT_EQ(run.code, 2) << run.output;
  EXPECT_NE(run.output.find("design_pmf"), std::string::npos) << run.output;
  const fs::path out = dir_ / "rec";
  const Outcome o = ncosim({"record-link", scenario_, "--link", "n2", "--out", out.string(),
                            "--runs", "2", "--periods", "150"});
  ASSERT_EQ(o.code, 0) << o.output;
  EXPECT_NE(o.output.find("no design_pmf on network link(s) 'n1', 'n2', 'n3', 'n4'"),
            std::string::npos)
      << o.output;
  EXPECT_EQ(ncosim::testing::split_lines(slurp(out / "n2.csv")).size(), 1U + 2 * 150);
}

TEST_F(Ladder, RecordsFitsWritesOrdinaryScenariosRunsThemPairedAndCompares) {
  const fs::path out = dir_ / "ladder";
  const Outcome o = ncosim(ladder(out, {"--family", "bernoulli", "--family", "delay"}));
  ASSERT_EQ(o.code, 0) << o.output;
  for (const char* f : {"network.toml", "bernoulli.toml", "delay.toml", "ladder.csv", "ladder.md",
                        "traces/n1.csv", "traces/n4.csv", "fits/n1.json", "runs/network/runs.csv",
                        "runs/delay/runs.csv", "compare/delay.md"}) {
    EXPECT_TRUE(fs::exists(out / f)) << f;
  }
  EXPECT_EQ(leftovers(out), 0);
  EXPECT_NE(o.output.find("Where each surrogate leaves the band"), std::string::npos) << o.output;
  // The network rung's design law is the delay fit's (fits/n1.json).
  const auto fit = nlohmann::json::parse(slurp(out / "fits" / "n1.json"));
  std::string law;
  for (const auto& f : fit["families"]) {
    if (f["family"] != "delay") continue;
    for (const auto& p : f["marginal_pmf"]) {
      std::string v = fmt::format("{}", p.get<double>());
      if (v.find_first_of(".e") == std::string::npos) v += ".0";  // a TOML float
      law += (law.empty() ? "" : ", ") + v;
    }
  }
  const std::string network = slurp(out / "network.toml");
  EXPECT_NE(network.find("design_pmf = [" + law + "]"), std::string::npos) << law << "\n"
                                                                           << network;
  // A surrogate is an ordinary scenario without the network; run alone, it is the campaign the
  // ladder ran (same runs.csv).
  const std::string delay = slurp(out / "delay.toml");
  EXPECT_EQ(delay.find("\n[[network]]"), std::string::npos) << delay;
  EXPECT_EQ(delay.find("kind = \"network\""), std::string::npos) << delay;
  const Outcome again =
      ncosim({"run", (out / "delay.toml").string(), "--out", (dir_ / "again").string(), "--quiet"});
  ASSERT_EQ(again.code, 0) << again.output;
  EXPECT_EQ(slurp(dir_ / "again" / "runs.csv"), slurp(out / "runs" / "delay" / "runs.csv"));
  // The traces are record-link's.
  const Outcome rec =
      ncosim({"record-link", scenario_, "--link", "n3", "--out", (dir_ / "rec").string(), "--runs",
              "3", "--periods", "200", "--set", "network[0].tx_power=-20", "--quiet"});
  ASSERT_EQ(rec.code, 0) << rec.output;
  EXPECT_EQ(slurp(dir_ / "rec" / "n3.csv"), slurp(out / "traces" / "n3.csv"));
  // ladder.csv: every estimator of every rung, with compare's verdict and the speed-up.
  const auto rows = ncosim::testing::split_lines(slurp(out / "ladder.csv"));
  ASSERT_EQ(rows.size(), 1U + 3 * 2);
  EXPECT_EQ(rows[0],
            "rung,estimator,verdict,band,test,pairs,network_mse,rung_mse,change,change_ci95_low,"
            "change_ci95_high,wall_seconds,speedup,note");
  for (std::size_t i = 3; i < rows.size(); ++i) {  // the surrogates' rows
    std::vector<std::string> cells;
    std::istringstream r(rows[i]);
    for (std::string c; std::getline(r, c, ',');) cells.push_back(c);
    ASSERT_GE(cells.size(), 13U) << rows[i];
    EXPECT_FALSE(cells[2].empty()) << rows[i];  // compare's verdict
    EXPECT_TRUE(cells[3] == "inside" || cells[3] == "inconclusive" || cells[3] == cells[2])
        << rows[i];  // the band
    EXPECT_EQ(cells[4], "paired") << rows[i];
    EXPECT_EQ(cells[5], "3") << rows[i];
    EXPECT_GT(std::stod(cells[12]), 1.0) << rows[i];  // faster than the network
  }
  // Without --replace a folder that holds files is refused; with it, replaced.
  const Outcome twice = ncosim(ladder(out, {"--family", "delay"}));
  EXPECT_EQ(twice.code, 2) << twice.output;
  EXPECT_NE(twice.output.find("--replace"), std::string::npos) << twice.output;
  EXPECT_TRUE(fs::exists(out / "bernoulli.toml"));
}

TEST_F(Ladder, BadInputOfEveryOptionIsExit2WithTheOptionNamedAndNothingWritten) {
  const fs::path out = dir_ / "bad";
  const std::string base = (kSource / "tests/cli/data/base.toml").string();
  const std::vector<std::pair<std::vector<std::string>, std::string>> bad{
      {{"--runs", "0"}, "--runs"},
      {{"--periods", "x"}, "--periods"},
      {{"--seed", "-1"}, "--seed"},
      {{"--family", "hmm"}, "--family: expected bernoulli, delay"},
      {{"--family", "delay", "--family", "delay"}, "--family: expected each family once"},
      {{"--tolerance", "0"}, "--tolerance"},
      {{"--tolerance", "1.5"}, "--tolerance"},
      {{"--alpha", "1"}, "--alpha"},
      {{"--starts", "0"}, "--starts"},
      {{"--max-iterations", "0"}, "--max-iterations"},
      {{"--threads", "-1"}, "--threads"},
      {{"--set", "run.warmup=-5"}, "run.warmup"},
      {{"--set", "link[0].position=[0.0, 0.0, 0.0, 1.0]"}, "position"},
      {{"--set", "sweep=[{key = \"run.warmup\", values = [10, 20]}]"}, "without [[sweep]]"},
  };
  for (const auto& [args, named] : bad) {
    const Outcome o = ncosim(ladder(out, args));
    EXPECT_EQ(o.code, 2) << args.back() << ": " << o.output;
    EXPECT_NE(o.output.find(named), std::string::npos) << o.output;
    EXPECT_FALSE(fs::exists(out)) << args.back();
    EXPECT_EQ(leftovers(out), 0) << args.back();
  }
  const Outcome none = ncosim({"ladder", base, "--out", out.string()});
  EXPECT_EQ(none.code, 2) << none.output;
  EXPECT_NE(none.output.find("expected a [[link]] of kind \"network\""), std::string::npos)
      << none.output;
  const Outcome actuator =
      ncosim({"ladder", (kSource / "tests/network/data/csma_actuator.toml").string(), "--out",
              out.string()});
  EXPECT_EQ(actuator.code, 2) << actuator.output;
  EXPECT_NE(actuator.output.find("actuator"), std::string::npos) << actuator.output;
  EXPECT_FALSE(fs::exists(out));
}

// Killed in its first write (the network campaign's export), after the links were recorded: OUT
// does not exist; the next ladder removes the staging folder the killed one left, and succeeds.
TEST_F(Ladder, AKilledLadderLeavesNothingInItsFolder) {
  const fs::path out = dir_ / "killed";
  const Outcome killed = ncosim(ladder(out, {"--family", "delay"}), "NCOSIM_TEST_KILL_AT=1 ");
  EXPECT_NE(killed.code, 0) << killed.output;
  EXPECT_FALSE(fs::exists(out));
  EXPECT_EQ(leftovers(out), 1);
  std::vector<std::string> args = ladder(out, {"--family", "delay"});
  args.erase(std::find(args.begin(), args.end(), "--quiet"));  // the removal is reported
  const Outcome o = ncosim(args);
  ASSERT_EQ(o.code, 0) << o.output;
  EXPECT_NE(o.output.find("removed 1 leftover folder(s) of an interrupted ladder"),
            std::string::npos)
      << o.output;
  EXPECT_EQ(leftovers(out), 0);
  EXPECT_TRUE(fs::exists(out / "delay.toml"));
}

}  // namespace
