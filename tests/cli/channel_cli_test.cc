// tests/cli/channel_cli_test.cc — the channel features through the ncosim executable: links.csv
// in every run, zipped sweep axes, Gilbert–Elliott by mean loss and mean burst (and its errors at
// FILE:LINE), and `ncosim fit` (its files, and exit 2 with FILE:LINE and nothing written for a
// trace with no packet, non-consecutive sequence numbers, fewer packets than parameters, and an
// unknown family, a delay beyond what the families hold).
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <stdlib.h>

#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

#include "cli/temp_dir_test.h"
#include "test_util.h"

namespace {

namespace fs = std::filesystem;
using Outcome = ncosim::testing::CommandOutcome;
using ncosim::testing::run_ncosim;
using ncosim::testing::split_lines;

class ChannelCli : public ncosim::testing::TempDirTest {
 protected:
  ChannelCli() : TempDirTest("ncosim_channel_") {}
  void SetUp() override {
    TempDirTest::SetUp();
    out_ = dir_ / "out";
    base_ =
        ncosim::testing::read_text(std::string(NCOSIM_SOURCE_DIR) + "/tests/cli/data/base.toml");
  }
  std::string with_link2(const std::string& link) {
    const std::string from = "name = \"net2\"\nkind = \"bernoulli\"\nloss = 0.2\n";
    std::string t = base_;
    const auto at = t.find(from);
    EXPECT_NE(at, std::string::npos);
    return t.replace(at, from.size(), "name = \"net2\"\n" + link);
  }
  fs::path out_;
  std::string base_;
};

TEST_F(ChannelCli, RunWritesLinksCsvWithARowPerLinkAndSender) {
  const Outcome o = run_ncosim({"run", write("s.toml", base_), "--out", out_.string(), "--quiet"});
  ASSERT_EQ(o.code, 0) << o.output;
  const auto l = split_lines(ncosim::testing::read_text((out_ / "links.csv").string()));
  ASSERT_EQ(l.size(), 3u);
  EXPECT_EQ(l[0],
            "link,kind,sender,runs,packets_sent,packets_delivered,delivered_ratio,nominal_"
            "delivered_ratio,delay_max,"
            "delay_pmf,nominal_delay_pmf,bursts,burst_mean,nominal_burst_mean,burst_p95,burst_max,"
            "state_occupancy,"
            "nominal_state_occupancy,step,mac_attempts,mac_retries,drops_queue,drops_channel_"
            "access,drops_no_ack,drops_out_of_range,busy_ratio,offered_rate,delivered_rate,"
            "delay_first,delay_last,delay_growth,delay_trend_p,loss_first,loss_last,loss_"
            "growth,loss_trend_p,overload");
  EXPECT_EQ(l[1].rfind("net1,delay,y1,4,8000,", 0), 0u) << l[1];
  // Not network links: the stack's 7 columns are empty; the overload test's 11 follow
  // (results/README.md, "Overload and growth"): stationary links, tested, `none`.
  std::vector<std::string> cells;
  std::istringstream row(l[1]);
  for (std::string c; std::getline(row, c, ',');) cells.push_back(c);
  ASSERT_EQ(cells.size(), 37u) << l[1];
  for (std::size_t i = 19; i < 26; ++i) EXPECT_EQ(cells[i], "") << i << ": " << l[1];
  EXPECT_EQ(cells[26], "1") << l[1];  // offered_rate: one sample per period
  EXPECT_EQ(cells[36], "none") << l[1];
  EXPECT_EQ(l[2].rfind("net2,bernoulli,y2,4,8000,", 0), 0u) << l[2];
}

TEST_F(ChannelCli, ZippedSweepsMoveTogetherAndCrossTheOtherAxes) {
  const std::string text =
      with_link2("kind = \"gilbert_elliott\"\nmean_loss = 0.1\nmean_burst = 2.0\n") +
      "\n[[sweep]]\nkey = \"link[1].mean_loss\"\nvalues = [0.05, 0.1, 0.2]\nzip = \"ge\"\n"
      "\n[[sweep]]\nkey = \"estimator[0].history\"\nvalues = [1, 2]\n"
      "\n[[sweep]]\nkey = \"link[1].mean_burst\"\nvalues = [1.5, 3.0, 6.0]\nzip = \"ge\"\n";
  const Outcome o = run_ncosim({"run", write("s.toml", text), "--out", out_.string(), "--runs", "2",
                                "--periods", "20000", "--quiet"});
  ASSERT_EQ(o.code, 0) << o.output;
  const auto l = split_lines(ncosim::testing::read_text((out_ / "links.csv").string()));
  ASSERT_EQ(l.size(), 1u + 6u * 2u);  // 3 zipped x 2 cases, 2 links each
  EXPECT_EQ(l[0].rfind("link[1].mean_loss,estimator[0].history,link[1].mean_burst,link,", 0), 0u)
      << l[0];
  const std::vector<std::string> expect{"0.05,1,1.5", "0.05,2,1.5", "0.1,1,3.0",
                                        "0.1,2,3.0",  "0.2,1,6.0",  "0.2,2,6.0"};
  for (std::size_t c = 0; c < 6; ++c) {
    const std::string& row = l[2 + 2 * c];  // the net2 row of case c
    EXPECT_EQ(row.rfind(expect[c] + ",net2,gilbert_elliott,", 0), 0u) << row;
    // The nominal loss and burst are the keys' values (exact conversion).
    std::vector<std::string> f;
    std::stringstream ss(row);
    for (std::string x; std::getline(ss, x, ',');) f.push_back(x);
    EXPECT_NEAR(1.0 - std::stod(f[10]), std::stod(f[0]), 1e-6) << row;
    EXPECT_NEAR(std::stod(f[16]), std::stod(f[2]), 1e-5) << row;
  }
}

TEST_F(ChannelCli, ZippedSweepsOfDifferentLengthsAreRejectedAtTheirLine) {
  const std::string text =
      base_ +
      "\n[[sweep]]\nkey = \"link[1].loss\"\nvalues = [0.1, 0.2]\nzip = \"a\"\n"
      "\n[[sweep]]\nkey = \"estimator[0].history\"\nvalues = [1, 2, 3]\nzip = \"a\"\n";
  const std::string file = write("s.toml", text);
  const Outcome o = run_ncosim({"run", file, "--out", out_.string(), "--quiet"});
  EXPECT_EQ(o.code, 2) << o.output;
  const auto l = split_lines(text);
  int line = 0;
  for (std::size_t i = 0; i < l.size(); ++i) {
    if (l[i] == "values = [1, 2, 3]") line = static_cast<int>(i) + 1;
  }
  EXPECT_NE(o.output.find(fmt::format("{}:{}:", file, line)), std::string::npos) << o.output;
  EXPECT_NE(o.output.find("expected 2 values like the other sweeps zipped as \"a\", got 3"),
            std::string::npos)
      << o.output;
  EXPECT_FALSE(fs::exists(out_ / "summary.csv"));
}

TEST_F(ChannelCli, GilbertElliottByMeanIsValidated) {
  struct Bad {
    std::string link, key, message;
  };
  const std::vector<Bad> bad{
      {"kind = \"gilbert_elliott\"\nmean_loss = 0.1\nmean_burst = 2.0\np_good_to_bad = 0.1\n",
       "p_good_to_bad", "expected either p_good_to_bad or mean_loss and mean_burst, got both"},
      {"kind = \"gilbert_elliott\"\nmean_loss = 0.6\nmean_burst = 2.0\nloss_bad = 0.5\n",
       "mean_loss",
       "expected loss_good < mean_loss < loss_bad, got mean_loss = 0.6 (0 < 0.6 < 0.5 fails)"},
      {"kind = \"gilbert_elliott\"\nmean_loss = 0.1\nmean_burst = 40.0\nloss_good = 0.05\nloss_bad "
       "= 0.2\n",
       "mean_burst", "expected mean_burst <"},
      // Numbers as written (before: 40.000000), and every range error says what it got.
      {"kind = \"gilbert_elliott\"\nmean_loss = 0.1\nmean_burst = 40\nloss_good = 0.05\nloss_bad = "
       "0.2\n",
       "mean_burst", "allow), got 40"},
      {"kind = \"gilbert_elliott\"\nmean_loss = 0.1\nmean_burst = 0.5\n", "mean_burst",
       "expected a finite mean burst length >= 1, got 0.5"},
      {"kind = \"gilbert_elliott\"\nmean_loss = 0.1\n", "mean_burst", "required"},
      {"kind = \"markov\"\ntransition = [[1.0]]\nloss = [0.1]\nstep = \"tick\"\n", "step", "tick"},
  };
  for (const auto& b : bad) {
    const std::string text = with_link2(b.link);
    const std::string file = write("s.toml", text);
    const Outcome o = run_ncosim({"run", file, "--out", out_.string(), "--quiet"});
    EXPECT_EQ(o.code, 2) << o.output;
    EXPECT_NE(o.output.find(file + ":"), std::string::npos) << o.output;
    EXPECT_NE(o.output.find("link[1]." + b.key), std::string::npos) << o.output;
    EXPECT_NE(o.output.find(b.message), std::string::npos) << o.output;
    EXPECT_FALSE(fs::exists(out_));
  }
}

TEST_F(ChannelCli, FitWritesTheLinkTableAndDiagnosticsAndTheTableRuns) {
  std::string trace = "seq,delay\n";
  // Bursty: 40 packets delivered, then 10 lost, repeated (with a delay-1 packet now and then).
  for (int i = 0; i < 5000; ++i)
    trace += fmt::format("{},{}\n", i, i % 50 >= 40 ? "" : (i % 7 == 0 ? "1" : "0"));
  const std::string file = write("trace.csv", trace);
  const Outcome o = run_ncosim(
      {"fit", file, "--out", out_.string(), "--family", "delay", "--family", "gilbert_elliott"});
  ASSERT_EQ(o.code, 0) << o.output;
  EXPECT_NE(o.output.find("gilbert_elliott"), std::string::npos) << o.output;
  // Each parameter with its 95 % interval, and the mean loss / mean burst of the Gilbert–Elliott
  // fit (issue 28): 10 of every 50 packets lost in runs of 10.
  EXPECT_NE(o.output.find("gilbert_elliott, selected by bic: estimates and 95 % intervals"),
            std::string::npos)
      << o.output;
  for (const auto& [name, truth] :
       {std::pair<std::string, double>{"mean_loss", 0.2}, {"mean_burst", 10.0}}) {
    const auto at = o.output.find("  " + name + " ");
    ASSERT_NE(at, std::string::npos) << o.output;
    std::istringstream line(o.output.substr(at, o.output.find('\n', at) - at));
    std::string n;
    double est = 0, lo = 0, hi = 0;
    char c = 0;
    line >> n >> est >> c >> lo >> c >> hi;
    EXPECT_NEAR(est, truth, 0.02 * truth) << o.output;
    EXPECT_LT(lo, est) << o.output;
    EXPECT_GT(hi, est) << o.output;
  }
  const std::string toml = ncosim::testing::read_text((out_ / "link.toml").string());
  EXPECT_NE(toml.find("[[link]]\nname = \"trace\"\nkind = \"markov\""), std::string::npos)
      << toml;  // GE + delays
  EXPECT_NE(toml.find("# delay (loglik"), std::string::npos) << toml;
  const auto csv = split_lines(ncosim::testing::read_text((out_ / "fit.csv").string()));
  ASSERT_GT(csv.size(), 20u);
  EXPECT_EQ(csv[0], "family,section,item,estimate,ci95_low,ci95_high,observed,interval");
  EXPECT_NE(std::find(csv.begin(), csv.end(), "gilbert_elliott,fit,selected,1,,,,"), csv.end());
  // The table is a valid [[link]]: paste it into a scenario in place of net2.
  std::string link = toml.substr(toml.find("kind ="));
  link = link.substr(0, link.find("\n\n") + 1);
  const Outcome run = run_ncosim({"check", write("s.toml", with_link2(link))});
  EXPECT_EQ(run.code, 0) << run.output << link;
}

TEST_F(ChannelCli, FitRejectsBadTracesWithFileLineAndWritesNothing) {
  struct Bad {
    std::string trace;
    std::vector<std::string> args;
    std::string where, message;
  };
  const std::vector<Bad> bad{
      {"seq,delay\n", {}, ":1:", "the trace holds no packet"},
      {"0,0\n1,\n3,0\n", {}, ":3:", "consecutive from 0"},
      {"0,0\n1,\n2,0\n1,0\n", {}, ":4:", "consecutive from 0"},
      {"0,0\n1,\n2,0\n",
       {"--family", "markov2"},
       ":3:",
       "fewer than the 4 parameters of the markov2 family"},
      {"0,0\n1,x\n", {}, ":2:", "non-negative integer delay"},
  };
  for (const auto& b : bad) {
    const std::string file = write("t.csv", b.trace);
    std::vector<std::string> args{"fit", file, "--out", out_.string()};
    args.insert(args.end(), b.args.begin(), b.args.end());
    const Outcome o = run_ncosim(args);
    EXPECT_EQ(o.code, 2) << o.output;
    EXPECT_NE(o.output.find(file + b.where), std::string::npos) << o.output;
    EXPECT_NE(o.output.find(b.message), std::string::npos) << o.output;
    EXPECT_FALSE(fs::exists(out_)) << b.trace;
  }
  const std::string file = write("t.csv", "0,0\n1,\n");
  const Outcome o = run_ncosim({"fit", file, "--out", out_.string(), "--family", "hmm"});
  EXPECT_EQ(o.code, 2);
  EXPECT_NE(
      o.output.find(
          "--family: expected bernoulli, delay, gilbert_elliott or markov2 .. markov8, got 'hmm'"),
      std::string::npos)
      << o.output;
  EXPECT_FALSE(fs::exists(out_));
}

TEST_F(ChannelCli, FitRefusesADelayBeyondWhatTheFamiliesHoldAtItsLine) {
  // Issue 29: 300 rows of delay 1 and one huge delay crashed (1e12: SIGSEGV; 2^63 - 2: double
  // free) or was silently counted as lost (2^62 - 1). Bad input at the row's line instead.
  for (const std::string delay :
       {"1000000000000", "9223372036854775806", "4611686018427387903", "1000001"}) {
    std::string trace = "seq,delay\n";
    for (int i = 0; i < 300; ++i) trace += fmt::format("{},{}\n", i, i == 150 ? delay : "1");
    const std::string file = write("t.csv", trace);
    const Outcome o = run_ncosim({"fit", file, "--out", out_.string()});
    EXPECT_EQ(o.code, 2) << delay << ": " << o.output;
    // Row 150 is on line 152 (after the header).
    EXPECT_NE(
        o.output.find(file +
                      ":152: delay: expected at most 1000000 periods (the largest delay the fit "
                      "families hold), got " +
                      delay),
        std::string::npos)
        << o.output;
    EXPECT_FALSE(fs::exists(out_)) << delay;
  }
}

}  // namespace
