// tests/sim/overload_test.cc — overload and growth told (sim/run/trend.h, sim/run/overload.h):
// the trend tests on hand-made series, the delay blocks of a run, their storage, the error blocks
// of the recorder, and the verdicts, notes and --fail-on-status lines from hand-made counters.
#include "sim/run/overload.h"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <boost/math/distributions/students_t.hpp>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <numeric>

#include "sim/run/campaign.h"
#include "sim/run/link_report.h"
#include "sim/run/trend.h"
#include "sim/store/store_format.h"
#include "test_util.h"

namespace ncosim::sim {
namespace {

BlockSeries line(std::size_t n, double a, double b, double wiggle = 0.0) {
  BlockSeries s;
  for (std::size_t i = 0; i < n; ++i) {
    const double t = (static_cast<double>(i) + 0.5) / static_cast<double>(n);
    s.t.push_back(t);
    s.y.push_back(a + b * t + wiggle * ((i * 7919) % 13 - 6.0));
  }
  return s;
}

TEST(Trend, LeastSquaresLine) {
  const auto l = fit_line(line(20, 3.0, 5.0));
  ASSERT_TRUE(l);
  EXPECT_NEAR(l->a, 3.0, 1e-12);
  EXPECT_NEAR(l->b, 5.0, 1e-12);
  EXPECT_FALSE(fit_line(line(2, 3.0, 5.0)));
  BlockSeries flat{{0.5, 0.5, 0.5}, {1.0, 2.0, 3.0}};
  EXPECT_FALSE(fit_line(flat));
}

TEST(Trend, StudentTOverTheRunsSlopes) {
  // Slopes 1, 2, 3: mean 2, sd 1, t = 2 sqrt(3) with 2 degrees of freedom.
  const boost::math::students_t t2(2.0);
  EXPECT_NEAR(slopes_p({1.0, 2.0, 3.0}),
              boost::math::cdf(boost::math::complement(t2, 2.0 * std::sqrt(3.0))), 1e-14);
  EXPECT_GT(slopes_p({-1.0, -2.0, -3.0}), 0.9);
  EXPECT_EQ(slopes_p({0.5, 0.5}), 0.0);  // equal and positive: certain
  EXPECT_EQ(slopes_p({0.0, 0.0}), 1.0);
  EXPECT_EQ(slopes_p({4.0}), 1.0);  // one slope: no spread to test with
}

TEST(Trend, MannKendallExactAndWithTies) {
  std::vector<double> up(30), flat(30, 2.0), down(30);
  for (std::size_t i = 0; i < 30; ++i) {
    up[i] = static_cast<double>(i) + 0.3 * std::sin(static_cast<double>(i));
    down[i] = -up[i];
  }
  EXPECT_LT(mann_kendall_p({up}), 1e-6);  // 30 points: the normal approximation
  EXPECT_EQ(mann_kendall_p({flat}), 1.0);
  EXPECT_EQ(mann_kendall_p({down}), 1.0);
  // Exact: 8 increasing points are 1 order of 8! = 40320; one swap of neighbours (S = 26) adds
  // the 7 orders with one inversion.
  const std::vector<double> eight{1, 2, 3, 4, 5, 6, 7, 8}, swapped{1, 2, 3, 5, 4, 6, 7, 8};
  EXPECT_NEAR(mann_kendall_p({eight}), 1.0 / 40320.0, 1e-18);
  EXPECT_NEAR(mann_kendall_p({swapped}), 8.0 / 40320.0, 1e-17);
  // Two runs: S summed (54), the inversions' law convolved: P(at most 1 inversion in all) =
  // (1 + 7 + 7) / 40320^2.
  EXPECT_NEAR(mann_kendall_p({eight, swapped}), 15.0 / (40320.0 * 40320.0), 1e-20);
  // A run that falls cancels one that grows: S = 0.
  std::vector<double> fall(eight.rbegin(), eight.rend());
  EXPECT_EQ(mann_kendall_p({eight, fall}), 1.0);
  // n = 3, S = 1: the orders with at most 1 inversion, 3 of 6.
  EXPECT_DOUBLE_EQ(mann_kendall_p({{1.0, 3.0, 2.0}}), 0.5);
  // With ties, the normal approximation: S = 2 of (1, 1, 2), Var = (3*2*11 - 2*1*9) / 18 = 8/3,
  // z = (2 - 1) / sqrt(8/3).
  EXPECT_NEAR(mann_kendall_p({{1.0, 1.0, 2.0}}),
              0.5 * std::erfc(1.0 / std::sqrt(8.0 / 3.0) / std::sqrt(2.0)), 1e-12);
  EXPECT_EQ(batch_means({1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16}, 8),
            (std::vector<double>{1.5, 3.5, 5.5, 7.5, 9.5, 11.5, 13.5, 15.5}));
  EXPECT_EQ(batch_means({1, 2, 3}, 8), (std::vector<double>{1, 2, 3}));
}

TEST(Trend, AcrossRunsOrWithinThem) {
  std::vector<BlockSeries> five;
  std::vector<double> slopes;
  for (int r = 0; r < 5; ++r) {
    five.push_back(line(20, 1.0, 2.0 + r, 0.1));
    slopes.push_back(fit_line(five.back())->b);
  }
  const auto across = trend_test(five, 16);
  ASSERT_TRUE(across);
  EXPECT_TRUE(across->across_runs);
  EXPECT_EQ(across->runs, 5u);
  EXPECT_DOUBLE_EQ(across->growth, std::accumulate(slopes.begin(), slopes.end(), 0.0) / 5.0);
  double first = 0.0, last = 0.0;
  for (const auto& s : five) {
    first += s.y.front() / 5.0;
    last += s.y.back() / 5.0;
  }
  EXPECT_DOUBLE_EQ(across->first, first);
  EXPECT_DOUBLE_EQ(across->last, last);
  EXPECT_DOUBLE_EQ(across->p, slopes_p(slopes));
  // Fewer than 5 runs: Mann–Kendall on each run's 8 batch means, summed; a short run is left out.
  const BlockSeries a = line(20, 1.0, 2.0, 0.1), b = line(24, 1.0, 3.0, 0.1);
  const auto within = trend_test({a, b, line(10, 1.0, 9.0)}, 16);
  ASSERT_TRUE(within);
  EXPECT_FALSE(within->across_runs);
  EXPECT_EQ(within->runs, 2u);
  EXPECT_DOUBLE_EQ(within->p, mann_kendall_p({batch_means(a.y, 8), batch_means(b.y, 8)}));
  EXPECT_LT(within->p, 1e-6);
  EXPECT_FALSE(trend_test({line(10, 1.0, 2.0)}, 16));
}

TEST(DelayBlocks, MergeKeepsBetweenKAnd2KBlocksAndEverySum) {
  for (const std::int64_t n : {31, 32, 63, 64, 65, 1000, 4097}) {
    models::LinkCounters c;
    std::int64_t delivered = 0, delay = 0;
    for (std::int64_t i = 0; i < n; ++i) {
      const std::int64_t d = i % 5 == 0 ? models::kLost : i % 3;
      c.record(d, -1);
    }
    const models::DelayBlocks& b = c.blocks;
    const auto full = static_cast<std::int64_t>(b.delivered.size());
    EXPECT_EQ(full * b.size + b.fill, n) << n;
    if (n >= 32) {
      EXPECT_GE(full, 32) << n;
      EXPECT_LT(full, 64) << n;
    }
    for (std::int64_t i = 0; i < full * b.size; ++i) {
      if (i % 5 == 0) continue;
      ++delivered;
      delay += i % 3;
    }
    EXPECT_EQ(std::accumulate(b.delivered.begin(), b.delivered.end(), std::int64_t{0}), delivered);
    EXPECT_EQ(std::accumulate(b.delay.begin(), b.delay.end(), std::int64_t{0}), delay);
  }
  // Several copies: the packet's first arrival is its delay.
  models::LinkCounters c;
  c.record(std::vector<std::int64_t>{3, 1}, -1);
  EXPECT_EQ(c.blocks.delay, std::vector<std::int64_t>{1});
}

TEST(DelayBlocks, StoredExactlyAndOlderBlobsReadWithout) {
  RunLinks links(2);
  for (int i = 0; i < 100; ++i) links[0].record(i % 4 == 0 ? models::kLost : i / 10, -1);
  const RunLinks back = deserialize_links(serialize_links(links));
  EXPECT_EQ(back[0].blocks.size, links[0].blocks.size);
  EXPECT_EQ(back[0].blocks.delivered, links[0].blocks.delivered);
  EXPECT_EQ(back[0].blocks.delay, links[0].blocks.delay);
  EXPECT_TRUE(back[1].blocks.delivered.empty());
  EXPECT_EQ(serialize_links(back), serialize_links(links));
  RunMetrics run(1);
  run[0].sse_blocks = {1.5, 2.5};
  EXPECT_EQ(deserialize_run(serialize_run(run))[0].sse_blocks, run[0].sse_blocks);
}

std::unique_ptr<Scenario> load_text(const std::string& text) {
  const auto file =
      std::filesystem::temp_directory_path() / fmt::format("ncosim_overload_{}.toml", ::getpid());
  std::ofstream(file) << text;
  auto sc = testing::load_one(file.string());
  std::filesystem::remove(file);
  return sc;
}

// A scalar plant, one sensor over `link`; the open-loop predictor's error grows on a random walk.
std::string scenario(const std::string& link, double a, int periods, int runs) {
  return fmt::format(R"(title = "t"
[run]
periods = {}
warmup = 20
runs = {}
seed = 5
[plant]
kind = "lti"
A = [[{}]]
Bw = [[1.0]]
W = [[1.0]]
[[sensor]]
name = "s"
C = [[1.0]]
R = [[1.0]]
link = "l"
[[link]]
name = "l"
{}
[[estimator]]
name = "Kalman"
kind = "kalman_extended"
max_delay = 2
[[estimator]]
name = "predictor"
kind = "open_loop"
)",
                     periods, runs, a, link);
}

CampaignResult campaign(const Scenario& sc) {
  CampaignOptions o;
  o.time_estimators = false;
  o.threads = 1;
  return run_campaign(sc, o);
}

TEST(ErrorBlocks, TheRecorderSumsTheCountedPeriodsInSixteenBlocks) {
  const auto sc = load_text(scenario("kind = \"bernoulli\"\nloss = 0.2", 0.9, 340, 1));
  const CampaignResult res = campaign(*sc);
  const EstimatorRunMetrics& m = res.runs.at(0).at(0);
  ASSERT_EQ(m.sse_blocks.size(), 16u);  // 320 counted periods: 16 blocks of 20
  EXPECT_NEAR(std::accumulate(m.sse_blocks.begin(), m.sse_blocks.end(), 0.0), m.sse, 1e-9 * m.sse);
  // Fewer counted periods than blocks: none.
  const auto short_sc = load_text(scenario("kind = \"bernoulli\"\nloss = 0.2", 0.9, 30, 1));
  EXPECT_TRUE(campaign(*short_sc).runs.at(0).at(0).sse_blocks.empty());
}

TEST(ErrorGrowth, ARandomWalksPredictorIsToldAStationaryFilterIsNot) {
  const auto sc = load_text(scenario("kind = \"bernoulli\"\nloss = 0.2", 1.0, 2000, 20));
  const CampaignResult res = campaign(*sc);
  const auto kalman = error_trend(res, 0);
  const auto predictor = error_trend(res, 1);
  ASSERT_TRUE(kalman && predictor);
  EXPECT_FALSE(error_grows(*kalman)) << kalman->p;
  EXPECT_TRUE(error_grows(*predictor)) << predictor->p;
  const std::string notes = growth_notes({}, {{}}, {sc.get()}, {&res});
  EXPECT_NE(notes.find("\"predictor\": its error grows through the run without diverging"),
            std::string::npos)
      << notes;
  EXPECT_EQ(notes.find("\"Kalman\""), std::string::npos) << notes;
}

// Counters of one flow over `runs` runs whose delays grow from 2 to 2 + `growth` periods, with a
// packet in `lose` lost (0: none).
std::vector<RunLinks> growing(int runs, std::int64_t packets, double growth, int lose) {
  std::vector<RunLinks> out;
  for (int r = 0; r < runs; ++r) {
    RunLinks l(1);
    for (std::int64_t i = 0; i < packets; ++i) {
      const bool lost = lose > 0 && (i + r) % lose == 0;
      const auto d = static_cast<std::int64_t>(
          2.0 + growth * static_cast<double>(i) / static_cast<double>(packets) + (i * 31 + r) % 3);
      l[0].record(lost ? models::kLost : d, -1);
    }
    out.push_back(std::move(l));
  }
  return out;
}

TEST(Overload, VerdictsFromCounters) {
  const auto sc = load_text(scenario("kind = \"bernoulli\"\nloss = 0.2", 0.9, 1000, 4));
  const auto flows = link_flows(*sc);
  CampaignResult res;
  res.runs.assign(4, RunMetrics{});
  res.link_runs = growing(4, 1000, 0.0, 0);
  EXPECT_EQ(flow_loads(*sc, res, flows).at(0).verdict, "none");
  res.link_runs = growing(4, 1000, 40.0, 0);
  FlowLoad load = flow_loads(*sc, res, flows).at(0);
  // Not a network link: a trend, never an overload.
  EXPECT_EQ(load.verdict, "trend");
  EXPECT_NEAR(load.offered_rate, 1.0, 1e-12);
  EXPECT_NEAR(load.delay->growth, 40.0, 1.0);
  EXPECT_TRUE(overloaded_flows({}, {{}}, {sc.get()}, {&res}).empty());
  const std::string notes = growth_notes({}, {{}}, {sc.get()}, {&res});
  EXPECT_NE(notes.find("link \"l\" (bernoulli), sender \"s\": grows through the run: mean delay"),
            std::string::npos)
      << notes;
  EXPECT_NE(notes.find("the link has no queue that could grow"), std::string::npos) << notes;
  // A growth below one period over the run is not told, significant or not.
  res.link_runs = growing(4, 1000, 0.9, 0);
  EXPECT_EQ(flow_loads(*sc, res, flows).at(0).verdict, "none");
  // Too few packets: not tested.
  res.link_runs = growing(4, 15, 40.0, 0);
  EXPECT_EQ(flow_loads(*sc, res, flows).at(0).verdict, "");
  // Losses that grow: a trend.
  res.link_runs.clear();
  for (int r = 0; r < 4; ++r) {
    RunLinks l(1);
    for (int i = 0; i < 1000; ++i) l[0].record((i * 7 + r) % 1000 < i ? models::kLost : 1, -1);
    res.link_runs.push_back(std::move(l));
  }
  load = flow_loads(*sc, res, flows).at(0);
  EXPECT_EQ(load.verdict, "trend");
  EXPECT_GT(load.loss->growth, 0.5);
  EXPECT_LT(load.loss->p, kTrendAlpha);
}

TEST(Overload, LinksCsvColumns) {
  const auto sc = load_text(scenario("kind = \"bernoulli\"\nloss = 0.2", 0.9, 1000, 4));
  CampaignResult res;
  res.runs.assign(4, RunMetrics{});
  res.link_runs = growing(4, 1000, 40.0, 4);
  const std::string csv = links_csv({}, {{}}, {sc.get()}, {&res});
  const std::string header = csv.substr(0, csv.find('\n'));
  EXPECT_NE(header.find(",busy_ratio,offered_rate,delivered_rate,delay_first,delay_last,delay_"
                        "growth,delay_trend_p,loss_first,loss_last,loss_growth,loss_trend_p,"
                        "overload"),
            std::string::npos)
      << header;
  const std::string row = csv.substr(csv.find('\n') + 1);
  EXPECT_NE(row.find(",1,0.75,"), std::string::npos) << row;  // offered 1, delivered 0.75
  EXPECT_NE(row.find(",trend\n"), std::string::npos) << row;
}

}  // namespace
}  // namespace ncosim::sim
