// tests/cli/record_link_cli_test.cc — `ncosim record-link` and the `trace` link's `segment`: the
// recorded fates are the campaign's (delivered counts as in links.csv, for an iid delay link and a
// time-driven Gilbert–Elliott link whose sensor sends every 3rd period), a replay with `segment`
// gives run r its own recorded packets (the Kalman filter's per-run errors are bit-identical to
// the campaign's), one trace per sweep case, and bad input is exit 2 with nothing written.
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <stdlib.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "cli/temp_dir_test.h"
#include "test_util.h"

namespace {

namespace fs = std::filesystem;
using Outcome = ncosim::testing::CommandOutcome;
using ncosim::testing::run_ncosim;
using ncosim::testing::split_lines;

std::vector<std::string> split(const std::string& line) {
  std::vector<std::string> out;
  std::istringstream in(line);
  for (std::string f; std::getline(in, f, ',');) out.push_back(f);
  return out;
}

std::string replace(std::string text, const std::string& from, const std::string& to) {
  const auto at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  return at == std::string::npos ? text : text.replace(at, from.size(), to);
}

// The runs.csv rows of one estimator, without the timing columns.
std::vector<std::string> rows_of(const fs::path& runs_csv, const std::string& estimator) {
  std::vector<std::string> out;
  for (const auto& l : split_lines(ncosim::testing::read_text(runs_csv.string()))) {
    if (l.find("," + estimator + ",") != std::string::npos)
      out.push_back(l.substr(0, l.find(",ok,")));
  }
  return out;
}

class RecordLinkCli : public ncosim::testing::TempDirTest {
 protected:
  RecordLinkCli() : TempDirTest("ncosim_record_") {}
  void SetUp() override {
    TempDirTest::SetUp();
    // base.toml with net2 a time-driven Gilbert–Elliott link and y2 sending every 3rd period.
    std::string t =
        ncosim::testing::read_text(std::string(NCOSIM_SOURCE_DIR) + "/tests/cli/data/base.toml");
    t = replace(
        t, "kind = \"bernoulli\"\nloss = 0.2\n",
        "kind = \"gilbert_elliott\"\np_good_to_bad = 0.05\np_bad_to_good = 0.3\nloss_good = 0.02\n"
        "loss_bad = 0.9\n");
    t = replace(t, "R = [[0.02]]\n", "R = [[0.02]]\nevery = 3\n");
    base_ = t;
  }
  std::string base_;
};

TEST_F(RecordLinkCli, RecordsTheCampaignsFatesAndASegmentedReplayReproducesIt) {
  const std::string file = write("s.toml", base_);
  const Outcome run =
      run_ncosim({"run", file, "--out", (dir_ / "run").string(), "--quiet", "--no-timing"});
  ASSERT_EQ(run.code, 0) << run.output;
  const auto links = split_lines(ncosim::testing::read_text((dir_ / "run" / "links.csv").string()));
  ASSERT_EQ(links.size(), 3u);
  for (const std::string link : {"net1", "net2"}) {
    const fs::path rec = dir_ / ("rec_" + link);
    const Outcome o =
        run_ncosim({"record-link", file, "--link", link, "--out", rec.string(), "--quiet"});
    ASSERT_EQ(o.code, 0) << o.output;
    const auto index = split_lines(ncosim::testing::read_text((rec / "record.csv").string()));
    ASSERT_EQ(index.size(), 2u);
    EXPECT_EQ(index[0], "link,file,runs,periods,segment,packets,delivered,delivered_ratio");
    const auto f = split(index[1]);
    ASSERT_EQ(f.size(), 8u) << index[1];
    const std::int64_t per_run = link == "net1" ? 2000 : 667;  // y2: periods 0, 3, ..., 1998
    EXPECT_EQ(f[0] + "," + f[1] + "," + f[2] + "," + f[3] + "," + f[4] + "," + f[5],
              fmt::format("{},{}.csv,4,2000,{},{}", link, link, per_run, 4 * per_run));
    // The delivered count is links.csv's for that link (its 6th column).
    const auto row = split(links[link == "net1" ? 1 : 2]);
    EXPECT_EQ(f[6], row[5]) << index[1] << "\n" << links[link == "net1" ? 1 : 2];
    const auto trace = split_lines(ncosim::testing::read_text((rec / (link + ".csv")).string()));
    ASSERT_EQ(trace.size(), static_cast<std::size_t>(4 * per_run + 1));
    EXPECT_EQ(trace[0], "seq,delay");
    EXPECT_EQ(trace[5].rfind("4,", 0), 0u);
  }
  // Replay both links from their records, run r its own segment.
  std::string replay = replace(base_, "kind = \"delay\"\npmf = [0.5, 0.3]\n",
                               "kind = \"trace\"\nfile = \"rec_net1/net1.csv\"\nsegment = 2000\n");
  replay = replace(
      replay,
      "kind = \"gilbert_elliott\"\np_good_to_bad = 0.05\np_bad_to_good = 0.3\nloss_good = 0.02\n"
      "loss_bad = 0.9\n",
      "kind = \"trace\"\nfile = \"rec_net2/net2.csv\"\nsegment = 667\n");
  const Outcome rp = run_ncosim({"run", write("replay.toml", replay), "--out",
                                 (dir_ / "replay").string(), "--quiet", "--no-timing"});
  ASSERT_EQ(rp.code, 0) << rp.output;
  // The Kalman filter uses what arrives (no design law): the same errors, run by run.
  const auto a = rows_of(dir_ / "run" / "runs.csv", "Kalman");
  const auto b = rows_of(dir_ / "replay" / "runs.csv", "Kalman");
  ASSERT_EQ(a.size(), 4u);
  EXPECT_EQ(a, b);
  // Without `segment` every run replays rows 0.. (run 0's packets): runs 1..3 differ.
  const Outcome whole =
      run_ncosim({"run", write("whole.toml", replace(replay, "segment = 2000\n", "")), "--out",
                  (dir_ / "whole").string(), "--quiet", "--no-timing"});
  ASSERT_EQ(whole.code, 0) << whole.output;
  const auto c = rows_of(dir_ / "whole" / "runs.csv", "Kalman");
  ASSERT_EQ(c.size(), 4u);
  EXPECT_EQ(c[0], a[0]);
  EXPECT_NE(c[1], a[1]);
}

TEST_F(RecordLinkCli, WritesOneTracePerSweepCase) {
  const std::string file =
      write("s.toml", base_ + "\n[[sweep]]\nkey = \"link[0].pmf\"\nvalues = [[0.5, 0.3], [0.9]]\n");
  const fs::path rec = dir_ / "rec";
  const Outcome o = run_ncosim(
      {"record-link", file, "--link", "net1", "--out", rec.string(), "--runs", "2", "--quiet"});
  ASSERT_EQ(o.code, 0) << o.output;
  const auto index = split_lines(ncosim::testing::read_text((rec / "record.csv").string()));
  ASSERT_EQ(index.size(), 3u);
  EXPECT_EQ(index[0],
            "link[0].pmf,link,file,runs,periods,segment,packets,delivered,delivered_ratio");
  EXPECT_EQ(index[1].rfind("\"[0.5, 0.3]\",net1,net1_case0.csv,2,2000,2000,4000,", 0), 0u)
      << index[1];
  EXPECT_EQ(index[2].rfind("[0.9],net1,net1_case1.csv,2,2000,2000,4000,", 0), 0u) << index[2];
  EXPECT_TRUE(fs::exists(rec / "net1_case0.csv"));
  EXPECT_TRUE(fs::exists(rec / "net1_case1.csv"));
}

TEST_F(RecordLinkCli, BadInputIsExit2AndWritesNothing) {
  const fs::path out = dir_ / "out";
  struct Bad {
    std::string scenario;
    std::vector<std::string> args;
    std::string message;
  };
  const std::string sod =
      replace(base_, "R = [[0.01]]\n", "R = [[0.01]]\npolicy = \"send_on_delta\"\ndelta = [0.1]\n");
  const std::vector<Bad> bad{
      {base_, {"--link", "net9"}, "--link: expected the name of a [[link]] of"},
      {sod, {"--link", "net1"}, "sends by policy \"send_on_delta\""},
      {base_,
       {"--link", "net1", "--runs", "30000"},
       "more than the 50000000 packets a trace link reads"},
      {base_, {"--link", "net1", "--threads", "-1"}, "--threads"},
      {base_, {"--link", "net1", "--threads", "lots"}, "--threads"},
  };
  for (const auto& b : bad) {
    std::vector<std::string> args{"record-link", write("s.toml", b.scenario), "--out",
                                  out.string()};
    args.insert(args.end(), b.args.begin(), b.args.end());
    const Outcome o = run_ncosim(args);
    EXPECT_EQ(o.code, 2) << o.output;
    EXPECT_NE(o.output.find(b.message), std::string::npos) << o.output;
    EXPECT_FALSE(fs::exists(out)) << b.message;
  }
  // `segment` out of range, or shorter than one run's packets: FILE:LINE of the key.
  std::string trace = "seq,delay\n";
  for (int i = 0; i < 4000; ++i) trace += fmt::format("{},{}\n", i, i % 5 == 0 ? "" : "0");
  write("t.csv", trace);
  for (const auto& [segment, message] : std::vector<std::pair<std::string, std::string>>{
           {"0", "expected an integer in 1..4000 (the trace's rows), got 0"},
           {"4001", "expected an integer in 1..4000"},
           {"1999", "expected a trace segment of at least 2000 packets"}}) {
    const std::string file =
        write("r.toml", replace(base_, "kind = \"delay\"\npmf = [0.5, 0.3]\n",
                                "kind = \"trace\"\nfile = \"t.csv\"\nsegment = " + segment + "\n"));
    const Outcome o = run_ncosim({"run", file, "--out", out.string(), "--quiet"});
    EXPECT_EQ(o.code, 2) << o.output;
    EXPECT_NE(o.output.find(file + ":"), std::string::npos) << o.output;
    EXPECT_NE(o.output.find("link[0].segment"), std::string::npos) << o.output;
    EXPECT_NE(o.output.find(message), std::string::npos) << o.output;
    EXPECT_FALSE(fs::exists(out));
  }
}

}  // namespace
