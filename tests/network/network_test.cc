// tests/network/network_test.cc — packet-level networks (network/): the wired case against delays
// computed by hand, the lockstep of ns-3 with the kernel's clock at its edges, reproducibility,
// and bad input. Built only with ns-3 (NCOSIM_NS3).
#include "network/network.h"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <toml++/toml.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <tuple>
#include <vector>

#include "cli/spawn_ncosim.h"
#include "config/config.h"
#include "network/network_fixtures.h"
#include "sim/scenario/registries.h"
#include "test_util.h"

namespace {

namespace fs = std::filesystem;
using ncosim::network::Drop;
using ncosim::network::Fate;
using ncosim::network::NetworkDesign;
using ncosim::network::NetworkRun;
using ncosim::network::Sender;
using ncosim::network::testing::start;

const fs::path kSource = NCOSIM_SOURCE_DIR;

using ncosim::network::testing::advance;
using ncosim::network::testing::burst;
using ncosim::network::testing::design;
using ncosim::network::testing::kMs;

// 1 Mb/s: a bit is 1000 ns, so every transmission time is a whole number of ns.
const char* kBus = "kind = \"csma\"\nrate = 1e6\ndelay = 5e-6\n";
// A packet of `payload` bytes on the bus: its 14-byte Ethernet header and 4-byte trailer included.
constexpr std::int64_t tx_ns(std::int64_t payload) { return (payload + 18) * 8 * 1000; }
constexpr std::int64_t kProp = 5000;

TEST(Wired, ALonePacketTakesItsTransmissionPlusPropagationTime) {
  auto s = start({design(kBus)}, {Sender{0, 64}, Sender{0, 200}}, 1, 0);
  s->send(0, 11, 0);
  auto f = advance(*s, 10 * kMs);
  ASSERT_EQ(f.size(), 1U);
  EXPECT_EQ(f[0].sender, 0);
  EXPECT_EQ(f[0].id, 11U);
  EXPECT_EQ(f[0].drop, Drop::kNone);
  EXPECT_EQ(f[0].time, tx_ns(64) + kProp);  // 656 us + 5 us
  s->send(1, 12, 20 * kMs);
  f = advance(*s, 30 * kMs);
  ASSERT_EQ(f.size(), 1U);
  EXPECT_EQ(f[0].sender, 1);
  EXPECT_EQ(f[0].time, 20 * kMs + tx_ns(200) + kProp);  // 1744 us + 5 us
}

// Three packets handed to one node at once leave it back to back, the Ethernet interframe gap of
// 96 bit times (96 us at 1 Mb/s, longer than the propagation delay, so the bus is idle again)
// apart: the i-th (0-based) is received after i (transmission + gap) + transmission + propagation.
TEST(Wired, ABurstFromOneNodeQueuesBackToBack) {
  auto s = start({design(kBus)}, {Sender{0, 64}}, 1, 0);
  for (std::uint64_t id = 0; id < 3; ++id) s->send(0, id, 3 * kMs);
  const auto f = advance(*s, 10 * kMs);
  ASSERT_EQ(f.size(), 3U);
  constexpr std::int64_t kGap = 96 * 1000;
  for (std::size_t i = 0; i < 3; ++i) {
    EXPECT_EQ(f[i].id, i);
    EXPECT_EQ(f[i].time,
              3 * kMs + static_cast<std::int64_t>(i) * (tx_ns(64) + kGap) + tx_ns(64) + kProp)
        << i;
  }
}

// A queue of 2 packets: of 4 handed over at once, one is on the wire, two wait, the fourth is
// dropped at once (cause queue).
TEST(Wired, AFullQueueDropsThePacket) {
  auto s = start({design(std::string(kBus) + "queue = 2\n")}, {Sender{0, 64}}, 1, 0);
  for (std::uint64_t id = 0; id < 4; ++id) s->send(0, id, 0);
  const auto f = advance(*s, 10 * kMs);
  ASSERT_EQ(f.size(), 4U);
  EXPECT_EQ(f[0].id, 3U);
  EXPECT_EQ(f[0].drop, Drop::kQueue);
  EXPECT_EQ(f[0].time, 0);
  for (std::size_t i = 1; i < 4; ++i) EXPECT_EQ(f[i].drop, Drop::kNone) << i;
}

// advance_to(t) processes every event at times <= t, including those scheduled at exactly t by
// events processed during the same call, and none after t. A send at the instant of a reception:
// both happen in that instant (the bus is idle again exactly then, so the new packet goes at once).
TEST(Lockstep, EveryEventUpToTheInstantAndNoneAfter) {
  constexpr std::int64_t kR = tx_ns(64) + kProp;  // 661 us
  auto s = start({design(kBus)}, {Sender{0, 64}, Sender{0, 64}}, 1, 0);
  s->send(0, 1, 0);
  EXPECT_TRUE(advance(*s, kR - 1).empty());
  s->send(1, 2, kR);
  auto f = advance(*s, kR);
  ASSERT_EQ(f.size(), 1U);
  EXPECT_EQ(f[0].id, 1U);
  EXPECT_EQ(f[0].time, kR);
  EXPECT_TRUE(advance(*s, 2 * kR - 1).empty());
  f = advance(*s, 2 * kR);
  ASSERT_EQ(f.size(), 1U);
  EXPECT_EQ(f[0].id, 2U);
  EXPECT_EQ(f[0].sender, 1);
  EXPECT_EQ(f[0].time, 2 * kR);
}

// Contention: four nodes sending at the same instant back off at random. ns-3's generator is
// seeded from (campaign seed, run): the same pair gives the same times, another run others.
std::vector<std::int64_t> contention_times(std::uint64_t seed, std::uint64_t run) {
  std::vector<Sender> senders(4, Sender{0, 100});
  auto s = start({design(kBus)}, senders, seed, run);
  std::vector<std::int64_t> times;
  for (int k = 0; k < 20; ++k) {
    for (int n = 0; n < 4; ++n) s->send(n, static_cast<std::uint64_t>(k * 4 + n), k * 5 * kMs);
    for (const Fate& f : advance(*s, k * 5 * kMs)) times.push_back(f.time);
  }
  for (const Fate& f : advance(*s, 200 * kMs)) times.push_back(f.time);
  return times;
}

TEST(Lockstep, TheSameSeedAndRunGiveTheSameNetwork) {
  const auto a = contention_times(7, 0);
  EXPECT_EQ(a.size(), 80U);
  EXPECT_EQ(a, contention_times(7, 0));
  EXPECT_NE(a, contention_times(7, 1));
  EXPECT_NE(a, contention_times(8, 0));
}

// ---- IEEE 802.15.4 ----

const char* kWpan = "kind = \"lr_wpan\"\n";

// One node 10 m from the sink, sending at 10 ms: its frame is acknowledged and delivered after the
// CSMA/CA back-off, its clear channel assessment, turnaround and airtime: at least (payload 32 + 11
// bytes of MAC and 6 of PHY header) x 32 us = 1.568 ms later, and well within 10 ms.
TEST(Wpan, ANodeInRangeDeliversItsFrame) {
  auto s = start({design(kWpan)}, {Sender{0, 32, 10.0, 0.0, 0.0}}, 1, 0);
  s->send(0, 5, 10 * kMs);
  const auto f = advance(*s, 100 * kMs);
  ASSERT_EQ(f.size(), 1U);
  EXPECT_EQ(f[0].drop, Drop::kNone);
  EXPECT_GE(f[0].time, 10 * kMs + (32 + 11 + 6) * 32'000);
  EXPECT_LT(f[0].time, 20 * kMs);
}

// The largest payload the device takes (114 bytes) is delivered. A larger one (which the scenario
// reader refuses) is refused by the device at once, and that is a drop, not a silent loss.
TEST(Wpan, TheLargestPayloadIsDeliveredALargerOneDropped) {
  auto s = start({design(kWpan)}, {Sender{0, 114, 10.0, 0.0, 0.0}, Sender{0, 115, 0.0, 10.0, 0.0}},
                 1, 0);
  s->send(1, 6, 5 * kMs);
  s->send(0, 5, 10 * kMs);
  const auto f = advance(*s, 100 * kMs);
  ASSERT_EQ(f.size(), 2U);
  EXPECT_EQ(f[0].id, 6U);
  EXPECT_EQ(f[0].drop, Drop::kQueue);
  EXPECT_EQ(f[0].time, 5 * kMs);
  EXPECT_EQ(f[1].id, 5U);
  EXPECT_EQ(f[1].drop, Drop::kNone);
}

// 300 m at 0 dBm: about -121 dBm at the sink, below the -112 dBm its receiver needs (the scenario
// reader refuses such a node; a session takes it); the frame is never acknowledged and the MAC
// drops it after its 3 retransmissions, a drop out of range. Its counters say so: 4 attempts, 3 of
// them retransmissions, one drop for that cause, and the time it was transmitting (4 frames of
// (32 + 11 + 6) bytes x 32 us; it hears nobody).
TEST(Wpan, ANodeOutOfRangeLosesItsFrameAfterItsRetries) {
  auto s = start({design(kWpan)}, {Sender{0, 32, 300.0, 0.0, 0.0}}, 1, 0);
  s->send(0, 5, 0);
  const auto f = advance(*s, 100 * kMs);
  ASSERT_EQ(f.size(), 1U);
  EXPECT_EQ(f[0].drop, Drop::kOutOfRange);
  const ncosim::network::MacCounters c = s->counters(0);
  EXPECT_EQ(c.attempts, 4U);
  EXPECT_EQ(c.retries, 3U);
  EXPECT_EQ(c.dropped[static_cast<int>(Drop::kOutOfRange)], 1U);
  EXPECT_EQ(c.dropped[static_cast<int>(Drop::kNoAck)], 0U);
  EXPECT_EQ(c.busy_ns, 4 * (32 + 11 + 6) * 32'000);
}

// Inside the sink's range but at its edge (112 m: ns-3's error model receives a 49-byte frame with
// probability 0.55, tests/network/wpan_psr_test.cc), frames are lost after their retries and those
// drops are collisions or noise (kNoAck), not out of range; a node 20 m away loses none, and its
// only attempts are its frames.
TEST(Wpan, ANodeAtTheEdgeOfRangeLosesFramesToNoise) {
  auto s = start({design(kWpan + std::string("max_frame_retries = 1\n"))},
                 {Sender{0, 32, 112.0, 0.0, 0.0}, Sender{0, 32, 0.0, 20.0, 0.0}}, 1, 0);
  for (std::uint64_t k = 0; k < 200; ++k) {
    s->send(0, 2 * k, static_cast<std::int64_t>(k) * 50 * kMs);
    s->send(1, 2 * k + 1, static_cast<std::int64_t>(k) * 50 * kMs + 25 * kMs);
  }
  const auto f = advance(*s, 200 * 50 * kMs + 1000 * kMs);
  ASSERT_EQ(f.size(), 400U);
  int lost = 0;
  for (const Fate& x : f) {
    if (x.sender == 1) {
      EXPECT_EQ(x.drop, Drop::kNone);
    } else if (x.drop != Drop::kNone) {
      EXPECT_EQ(x.drop, Drop::kNoAck);
      ++lost;
    }
  }
  EXPECT_GT(lost, 0);
  const ncosim::network::MacCounters edge = s->counters(0), near = s->counters(1);
  EXPECT_EQ(edge.dropped[static_cast<int>(Drop::kNoAck)], static_cast<std::uint64_t>(lost));
  EXPECT_GT(edge.retries, static_cast<std::uint64_t>(lost));  // every loss was retried once
  EXPECT_EQ(edge.attempts - edge.retries, 200U);
  EXPECT_EQ(near.attempts, 200U);
  EXPECT_EQ(near.retries, 0U);
  EXPECT_GT(near.busy_ns, 200 * (32 + 11 + 6) * 32'000);  // its frames, and what it heard
}

// Ten nodes that send at the same instant contend: every packet gets exactly one fate (delivered
// or dropped), whatever the retransmissions, and a run is reproducible.
std::vector<Fate> wpan_burst(std::uint64_t run) { return burst(kWpan, 40, run); }

TEST(Wpan, ContendingNodesGetOneFatePerPacket) {
  std::vector<Fate> f = wpan_burst(0);
  ASSERT_EQ(f.size(), 50U);
  std::vector<int> seen(50, 0);
  for (const Fate& x : f) ++seen[static_cast<std::size_t>(x.id)];
  for (int c : seen) EXPECT_EQ(c, 1);
  const auto again = wpan_burst(0);
  ASSERT_EQ(again.size(), f.size());
  for (std::size_t i = 0; i < f.size(); ++i) EXPECT_EQ(again[i].time, f[i].time) << i;
}

// ---- through the executable ----

using Outcome = ncosim::testing::CommandOutcome;
Outcome ncosim(const std::vector<std::string>& args) { return ncosim::testing::run_ncosim(args); }

class NetworkCli : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           fmt::format("ncosim_network_{}_{}", ::getpid(),
                       ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  static std::string slurp(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
  }
  // Column `column` of links.csv's rows, in order.
  static std::vector<std::string> links_column(const fs::path& out, const std::string& column) {
    std::istringstream in(slurp(out / "links.csv"));
    std::string line;
    std::getline(in, line);
    std::vector<std::string> header, values;
    std::istringstream h(line);
    for (std::string c; std::getline(h, c, ',');) header.push_back(c);
    const auto at = std::find(header.begin(), header.end(), column) - header.begin();
    while (std::getline(in, line)) {
      std::istringstream r(line);
      std::vector<std::string> cells;
      for (std::string c; std::getline(r, c, ',');) cells.push_back(c);
      values.push_back(static_cast<std::size_t>(at) < cells.size() ? cells[at] : "");
    }
    return values;
  }
  fs::path dir_;
};

// The 1-based line of the first occurrence of `what` in `text`.
int line_of(const std::string& text, const std::string& what) {
  const auto at = text.find(what);
  return 1 + static_cast<int>(std::count(text.begin(), text.begin() + static_cast<long>(at), '\n'));
}

const std::string kBoundary = (kSource / "tests/network/data/csma_boundary.toml").string();
const std::string kContention = (kSource / "tests/network/data/csma_contention.toml").string();

// Each packet of csma_boundary.toml is received exactly one period after it is sent: it is used
// at that boundary's update (delay 1). 1 ns less propagation: still delay 1; 1 us more: delay 2.
TEST_F(NetworkCli, AReceptionAtAPeriodBoundaryIsUsedAtThatBoundary) {
  for (const auto& [delay, pmf] : std::vector<std::pair<std::string, std::string>>{
           {"5e-6", "0;1"}, {"4.999e-6", "0;1"}, {"6e-6", "0;0;1"}}) {
    const fs::path out = dir_ / ("d" + delay);
    const Outcome o = ncosim(
        {"run", kBoundary, "--out", out.string(), "--quiet", "--set", "network[0].delay=" + delay});
    ASSERT_EQ(o.code, 0) << o.output;
    EXPECT_EQ(links_column(out, "delay_pmf"), std::vector<std::string>{pmf}) << delay;
    EXPECT_EQ(links_column(out, "delivered_ratio"), std::vector<std::string>{"1"}) << delay;
  }
}

// Contention, queueing and drops, and the run is a pure function of (scenario, seed, run): one
// thread, two threads, and two shards merged give the same bytes.
TEST_F(NetworkCli, ARunIsTheSameWhateverTheThreadsAndShards) {
  auto run = [&](const std::string& name, std::vector<std::string> extra) {
    std::vector<std::string> args{"run",     kContention,  "--out", (dir_ / name).string(),
                                  "--quiet", "--no-timing"};
    args.insert(args.end(), extra.begin(), extra.end());
    const Outcome o = ncosim(args);
    EXPECT_EQ(o.code, 0) << o.output;
  };
  run("t1", {"--threads", "1"});
  run("t2", {"--threads", "2"});
  run("s1", {"--shard", "1/2"});
  run("s2", {"--shard", "2/2"});
  const Outcome m =
      ncosim({"merge", (dir_ / "m").string(), (dir_ / "s1").string(), (dir_ / "s2").string()});
  ASSERT_EQ(m.code, 0) << m.output;
  const std::string runs = slurp(dir_ / "t1" / "runs.csv");
  EXPECT_FALSE(runs.empty());
  EXPECT_EQ(runs, slurp(dir_ / "t2" / "runs.csv"));
  EXPECT_EQ(runs, slurp(dir_ / "m" / "runs.csv"));
  EXPECT_EQ(slurp(dir_ / "t1" / "links.csv"), slurp(dir_ / "t2" / "links.csv"));
  EXPECT_EQ(slurp(dir_ / "t1" / "links.csv"), slurp(dir_ / "m" / "links.csv"));
  // Two sensors per node and a queue of 4 on a 1 Mb/s bus: every packet gets through, with
  // delays of one period or more (nothing arrives in the period it is sent).
  for (const auto& pmf : links_column(dir_ / "t1", "delay_pmf")) EXPECT_EQ(pmf.rfind("0;", 0), 0U);
  // The stack's columns are in those bytes. A node is its link, so the rows of a link's two
  // sensors show the same node's counters: it put every packet it did not drop on the wire once
  // (ns-3's CSMA has no retransmissions), at least those delivered; the bus exposes no busy time.
  const fs::path t1 = dir_ / "t1";
  const auto link = links_column(t1, "link");
  const auto attempts = links_column(t1, "mac_attempts");
  const auto delivered = links_column(t1, "packets_delivered");
  std::map<std::string, long long> node_attempts, node_delivered;
  for (std::size_t i = 0; i < link.size(); ++i) {
    if (node_attempts.count(link[i]) != 0U) {
      EXPECT_EQ(node_attempts[link[i]], std::stoll(attempts[i])) << i;
    }
    node_attempts[link[i]] = std::stoll(attempts[i]);
    node_delivered[link[i]] += std::stoll(delivered[i]);
    EXPECT_EQ(links_column(t1, "mac_retries")[i], "0") << i;
    EXPECT_EQ(links_column(t1, "busy_ratio")[i], "") << i;
  }
  ASSERT_EQ(node_attempts.size(), 2U);
  for (const auto& [name, n] : node_attempts) {
    EXPECT_GE(n, node_delivered[name]) << name;
    EXPECT_GT(node_delivered[name], 0) << name;
  }
}

// The shipped 802.15.4 star runs (with run 0's trace), and the jump observer's row says that its
// design model is not what the network does (summary.csv model_check), naming the network.
TEST_F(NetworkCli, TheWsnStarRunsAndItsDesignNoteNamesTheNetwork) {
  const fs::path out = dir_ / "wsn";
  const Outcome o = ncosim({"run", (kSource / "scenarios/wsn_star.toml").string(), "--out",
                            out.string(), "--runs", "2", "--periods", "300", "--quiet", "--trace"});
  ASSERT_EQ(o.code, 0) << o.output;
  // Run 0's trace, simulated in a process of its own after the campaign: 300 periods + header.
  const std::string trace = slurp(out / "trajectory.csv");
  EXPECT_EQ(std::count(trace.begin(), trace.end(), '\n'), 301);
  EXPECT_NE(slurp(out / "summary.csv")
                .find("network 'wsn' (lr_wpan): losses and delays come from its simulation"),
            std::string::npos);
  EXPECT_EQ(links_column(out, "link"), (std::vector<std::string>{"n1", "n2", "n3", "n4"}));
  // What each node's stack did: one attempt per packet at least, retries among them, and the
  // share of the time its transceiver was busy (its frames, and what it heard of the others').
  const auto sent = links_column(out, "packets_sent");
  const auto attempts = links_column(out, "mac_attempts");
  const auto retries = links_column(out, "mac_retries");
  const auto busy = links_column(out, "busy_ratio");
  ASSERT_EQ(attempts.size(), 4U);
  for (std::size_t i = 0; i < 4; ++i) {
    EXPECT_GE(std::stoll(attempts[i]), std::stoll(sent[i])) << i;
    EXPECT_LT(std::stoll(retries[i]), std::stoll(attempts[i])) << i;
    EXPECT_GT(std::stod(busy[i]), 0.0) << i;
    EXPECT_LT(std::stod(busy[i]), 0.5) << i;
  }
  for (const auto& c : links_column(out, "drops_out_of_range")) EXPECT_EQ(c, "0");
}

// record-link on a network link: each run simulated with the whole network (every other node
// contending), its trace fits, and its losses are those links.csv counts for the same runs: the
// packets in links.csv are those whose fate was known when the run ended, the trace has the few
// still in the network then too (ns-3 runs on until they have one).
TEST_F(NetworkCli, RecordLinkOnANetworkLinkFitsAndMatchesLinksCsv) {
  const std::string scenario = (kSource / "scenarios/wsn_star.toml").string();
  const std::vector<std::string> common{"--runs", "3",     "--periods",
                                        "400",    "--set", "network[0].tx_power=-20"};
  std::vector<std::string> run{"run",     scenario,     "--out", (dir_ / "run").string(),
                               "--quiet", "--no-timing"};
  run.insert(run.end(), common.begin(), common.end());
  const Outcome r = ncosim(run);
  ASSERT_EQ(r.code, 0) << r.output;
  std::vector<std::string> rec{"record-link",           scenario, "--link", "n1", "--out",
                               (dir_ / "rec").string(), "--quiet"};
  rec.insert(rec.end(), common.begin(), common.end());
  const Outcome o = ncosim(rec);
  ASSERT_EQ(o.code, 0) << o.output;
  std::istringstream trace(slurp(dir_ / "rec" / "n1.csv"));
  std::string line;
  std::getline(trace, line);
  long long rows = 0, delivered = 0;
  while (std::getline(trace, line)) {
    ++rows;
    delivered += line.back() != ',' ? 1 : 0;
  }
  EXPECT_EQ(rows, 3 * 400);  // 3 runs x 400 periods, n1's one sensor
  const long long sent = std::stoll(links_column(dir_ / "run", "packets_sent")[0]);
  const long long got = std::stoll(links_column(dir_ / "run", "packets_delivered")[0]);
  EXPECT_LE(sent, rows);
  EXPECT_GE(sent, rows - 3 * 10);  // at most a few periods' packets unsettled per run
  EXPECT_GE(delivered, got);
  EXPECT_LE(delivered - got, rows - sent);
  EXPECT_LT(got, sent);  // -20 dBm: 20 m is near the edge of range, some packets are lost
  std::cout << fmt::format(
      "record-link n1: {} packets, {} delivered; links.csv: {} sent, {} "
      "delivered\n",
      rows, delivered, sent, got);
  const Outcome fit =
      ncosim({"fit", (dir_ / "rec" / "n1.csv").string(), "--out", (dir_ / "fit").string()});
  ASSERT_EQ(fit.code, 0) << fit.output;
  EXPECT_TRUE(fs::exists(dir_ / "fit" / "link.toml"));
}

// Issue 40 part 7: record-link at a 1e-9 s period drained the network period by period (6e10
// steps up to 60 s) and ran for minutes, then wrote delays `fit` refuses without a word. Now it
// ends in seconds, its delays are the network's (a fate carries its own time), and it says at
// once why fit will refuse them.
TEST_F(NetworkCli, RecordLinkAtANanosecondPeriodEndsAndSaysWhyFitRefusesIt) {
  const std::string scenario = (kSource / "scenarios/wsn_star.toml").string();
  const auto begin = std::chrono::steady_clock::now();
  const Outcome o =
      ncosim({"record-link", scenario, "--link", "n1", "--out", (dir_ / "rec").string(), "--runs",
              "2", "--periods", "300", "--set", "run.period=1e-9", "--set", "run.warmup=0"});
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - begin).count();
  ASSERT_EQ(o.code, 0) << o.output;
  EXPECT_LT(seconds, 60.0);  // 2 s measured; it did not end in 30 s before
  EXPECT_NE(o.output.find("ncosim: note: case 1: link 'n1' delivered packets up to "),
            std::string::npos)
      << o.output;
  EXPECT_NE(o.output.find("`ncosim fit` takes delays up to 1000000 periods: a longer run.period"),
            std::string::npos)
      << o.output;
  const Outcome fit =
      ncosim({"fit", (dir_ / "rec" / "n1.csv").string(), "--out", (dir_ / "fit").string()});
  EXPECT_EQ(fit.code, 2) << fit.output;
  EXPECT_NE(fit.output.find("expected at most 1000000 periods"), std::string::npos) << fit.output;
}

// Issue 40 part 7: a network's memory is estimated too. Packets made faster than the channel
// carries wait in the nodes' queues (ns-3's 802.15.4 queue has no bound: 20 Poisson nodes at
// 20,000 packets/s held 435 MB after 3 s); the estimate bounds the peak RSS measured (1.3 to 1.7
// times it, network/ns3/*.cc) and is refused above --max-memory naming the key; saturated
// nodes hold two packets each and are not refused for their queues.
TEST_F(NetworkCli, OverloadedQueuesAreRefusedUnderTheMemoryLimit) {
  std::string star = slurp(kSource / "scenarios/wsn_star.toml");
  star.replace(star.find("runs = 20"), 9, "runs = 2");  // 1 or 2 workers at once on any machine
  const fs::path file = dir_ / "queues.toml";
  std::ofstream(file) << star
                      << "\n[[background]]\nnetwork = \"wsn\"\nnodes = 20\nrate = 2000\n"
                         "position = [10.0, 0.0, 0.0]\n";
  const Outcome o = ncosim({"check", file.string(), "--max-memory", "500"});
  EXPECT_EQ(o.code, 2) << o.output;
  EXPECT_NE(o.output.find(fmt::format("queues.toml:{}: key 'background[0].rate': the networks' "
                                      "simulation needs an estimated ",
                                      line_of(slurp(file), "rate = 2000"))),
            std::string::npos)
      << o.output;
  EXPECT_NE(o.output.find("of waiting packets), above the memory limit of 500 MB (--max-memory)"),
            std::string::npos)
      << o.output;
  EXPECT_EQ(ncosim({"check", file.string(), "--max-memory", "2000"}).code, 0);
  std::string saturated = slurp(file);
  saturated.replace(saturated.find("rate = 2000"), 11, "rate = \"saturated\"");
  std::ofstream(file) << saturated;
  const Outcome s = ncosim({"check", file.string(), "--max-memory", "500", "--max-work", "1e9"});
  EXPECT_EQ(s.code, 0) << s.output;
}

// Background nodes on an 802.11a network: their traffic delays the sensors' packets
// (the sensors' links only in links.csv), and the run is the same with one thread or two.
TEST_F(NetworkCli, BackgroundTrafficContendsWithTheSensors) {
  const std::string file = (kSource / "tests/network/data/wifi_background.toml").string();
  auto run = [&](const std::string& scenario, const std::string& name, const std::string& threads) {
    const Outcome o =
        ncosim({"run", scenario, "--out", (dir_ / name).string(), "--quiet", "--no-timing",
                "--runs", "2", "--periods", "100", "--threads", threads});
    EXPECT_EQ(o.code, 0) << o.output;
  };
  run(file, "t1", "1");
  run(file, "t2", "2");
  EXPECT_EQ(slurp(dir_ / "t1" / "runs.csv"), slurp(dir_ / "t2" / "runs.csv"));
  EXPECT_EQ(slurp(dir_ / "t1" / "links.csv"), slurp(dir_ / "t2" / "links.csv"));
  EXPECT_EQ(links_column(dir_ / "t1", "link"), (std::vector<std::string>{"n1", "n2"}));
  std::string quiet = slurp(file);
  quiet.erase(quiet.find("[[background]]"),
              quiet.find("[[sensor]]") - quiet.find("[[background]]"));
  std::ofstream(dir_ / "quiet.toml") << quiet;
  run((dir_ / "quiet.toml").string(), "q", "1");
  // Alone, each packet is delivered within its period (used at the next update: delay 1); among
  // the background's 1500-byte frames at 6 Mb/s, many wait several periods.
  for (std::size_t l = 0; l < 2; ++l) {
    EXPECT_EQ(links_column(dir_ / "q", "delivered_ratio")[l], "1") << l;
    EXPECT_EQ(links_column(dir_ / "q", "delay_max")[l], "1") << l;
    EXPECT_GT(std::stoi(links_column(dir_ / "t1", "delay_max")[l]), 5) << l;
  }
}

// A worker process that dies in the middle of a run (as ns-3 aborts on a failed assertion) ends
// the campaign with exit 1 and a message naming the run, never silently; the runs finished before
// are kept in the run store, and --resume completes the campaign.
TEST_F(NetworkCli, AWorkerThatDiesIsReportedAndResumeCompletes) {
  const fs::path out = dir_ / "wsn";
  const std::string log = (dir_ / "log.txt").string();
  const std::vector<std::string> args{"run",        (kSource / "scenarios/wsn_star.toml").string(),
                                      "--out",      out.string(),
                                      "--runs",     "30",
                                      "--periods",  "1000",
                                      "--threads",  "2",
                                      "--no-timing"};
  if (!fs::exists(fmt::format("/proc/{}/task/{}/children", ::getpid(), ::getpid())))
    GTEST_SKIP() << "this kernel does not list a process's children (CONFIG_PROC_CHILDREN)";
  const pid_t pid = ncosim::testing::spawn_ncosim(args, log);
  ASSERT_GT(pid, 0);
  pid_t child = -1;
  for (int i = 0; i < 200 && child < 0; ++i) {  // its first worker process
    ::usleep(20'000);
    std::ifstream in(fmt::format("/proc/{}/task/{}/children", pid, pid));
    in >> child;
    if (!in) child = -1;
  }
  ASSERT_GT(child, 0);
  ::usleep(300'000);  // some runs done
  ::kill(child, SIGKILL);
  int status = 0;
  ASSERT_EQ(::waitpid(pid, &status, 0), pid);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 1);
  const std::string text = slurp(log);
  EXPECT_NE(text.find("its worker process ended without a result (signal 9)"), std::string::npos)
      << text;
  std::vector<std::string> resume = args;
  resume.push_back("--resume");
  resume.push_back("--quiet");
  const Outcome o = ncosim(resume);
  ASSERT_EQ(o.code, 0) << o.output;
  const Outcome whole = ncosim({"run", (kSource / "scenarios/wsn_star.toml").string(), "--out",
                                (dir_ / "whole").string(), "--runs", "30", "--periods", "1000",
                                "--no-timing", "--quiet"});
  ASSERT_EQ(whole.code, 0) << whole.output;
  EXPECT_EQ(slurp(out / "runs.csv"), slurp(dir_ / "whole" / "runs.csv"));
  // The 802.15.4 nodes' stack counters too, over two worker processes and a resume.
  EXPECT_EQ(slurp(out / "links.csv"), slurp(dir_ / "whole" / "links.csv"));
  EXPECT_NE(links_column(out, "busy_ratio").at(0), "");
}

// A run whose ns-3 fails an NS_FATAL_ERROR (here the test hook NCOSIM_TEST_CRASH_RUN of
// network/ns3/ns3_engine.cc, which makes run 1's ns-3 fail inside Simulator::Run) does not stop the
// campaign: the message names the run and carries ns-3's text, the run's rows in runs.csv have
// status network_failure, the rows of summary.csv too (no mse, as for a diverged run), the other
// runs are those of a campaign without the crash, and the exit status is 3 (results written).
TEST_F(NetworkCli, ARunWhoseNs3AbortsGetsAStatusAndTheOthersGoOn) {
  auto run = [&](const std::string& name) {
    return ncosim({"run", (kSource / "scenarios/wsn_star.toml").string(), "--out",
                   (dir_ / name).string(), "--runs", "3", "--periods", "300", "--threads", "2",
                   "--no-timing", "--quiet"});
  };
  ::setenv("NCOSIM_TEST_CRASH_RUN", "1", 1);
  const Outcome crashed = run("crashed");
  ::unsetenv("NCOSIM_TEST_CRASH_RUN");
  const Outcome whole = run("whole");
  ASSERT_EQ(whole.code, 0) << whole.output;
  EXPECT_EQ(crashed.code, 3) << crashed.output;
  const std::string said =
      "ncosim: run 1: network_failure: its process ended abnormally (signal 6): "
      "msg=\"NCOSIM_TEST_CRASH_RUN: run 1 fails\"";
  const auto at = crashed.output.find(said);
  EXPECT_NE(at, std::string::npos) << crashed.output;
  EXPECT_EQ(crashed.output.find(said, at + 1), std::string::npos) << "said once";
  EXPECT_NE(crashed.output.find("\"Kalman\": network_failure"), std::string::npos);
  // runs.csv: run 1's rows are failures; every other row is the crash-free campaign's.
  std::istringstream a(slurp(dir_ / "crashed" / "runs.csv"));
  std::istringstream b(slurp(dir_ / "whole" / "runs.csv"));
  std::string la, lb;
  int failed = 0, same = 0;
  while (std::getline(a, la) && std::getline(b, lb)) {
    if (la.rfind("1,", 0) == 0) {
      EXPECT_NE(la.find(",1,network_failure,"), std::string::npos) << la;
      ++failed;
    } else {
      EXPECT_EQ(la, lb);
      ++same;
    }
  }
  EXPECT_EQ(failed, 2);    // two estimators
  EXPECT_EQ(same, 1 + 4);  // the header, runs 0 and 2
  const std::string summary = slurp(dir_ / "crashed" / "summary.csv");
  EXPECT_NE(summary.find("Kalman,kalman_extended,3,,,"), std::string::npos) << summary;
  EXPECT_NE(summary.find(",network_failure,"), std::string::npos) << summary;
}

// Actuator links over a network: the commands of csma_actuator.toml arrive 756 us after they
// are sent (computed by hand there). With a period of 757 us each arrives before the next plant
// step: runs.csv is that of a link that delivers every command, and links.csv gives every
// command delay 0. With a period of 756 us each arrives exactly at the next plant step, late:
// runs.csv is that of a link that loses every command, and links.csv gives every command delay 1.
TEST_F(NetworkCli, AnActuatorsCommandsCrossTheBusInTheTimeComputedByHand) {
  const std::string kActuator = (kSource / "tests/network/data/csma_actuator.toml").string();
  const std::string text = slurp(kActuator);
  const std::string net_link =
      "kind = \"network\"\nnetwork = \"bus\"\nbytes = 64\ndesign_pmf = [1.0]\n";
  auto variant = [&](const std::string& name, const std::string& link) {
    std::string t = text;
    t.replace(t.find(net_link), net_link.size(), link);
    // The bus then carries nothing: the network has no sender left.
    t.replace(t.find("[[network]]"), t.find("[[link]]") - t.find("[[network]]"), "");
    const fs::path f = dir_ / (name + ".toml");
    std::ofstream(f) << t;
    return f.string();
  };
  const std::string ideal = variant("ideal", "kind = \"bernoulli\"\nloss = 0.0\n");
  const std::string lost = variant("lost", "kind = \"bernoulli\"\nloss = 1.0\n");
  auto run = [&](const std::string& file, const std::string& name, const std::string& period) {
    const Outcome o = ncosim({"run", file, "--out", (dir_ / name).string(), "--quiet",
                              "--no-timing", "--set", "run.period=" + period});
    EXPECT_EQ(o.code, 0) << o.output;
    return slurp(dir_ / name / "runs.csv");
  };
  for (const auto& [period, pmf, same_as] :
       std::vector<std::tuple<std::string, std::string, std::string>>{{"0.000757", "1", ideal},
                                                                      {"0.000756", "0;1", lost}}) {
    const std::string net = run(kActuator, "net" + period, period);
    EXPECT_FALSE(net.empty());
    EXPECT_EQ(net, run(same_as, "ref" + period, period)) << period;
    EXPECT_EQ(links_column(dir_ / ("net" + period), "delay_pmf"), std::vector<std::string>{pmf})
        << period;
  }
}

// An actuator link over the 802.15.4 star: its commands contend with the four sensors' packets
// (the controller's transmitter beside the sink), and the run is the same on 1 and 2 threads.
TEST_F(NetworkCli, AnActuatorLinkOverTheWsnStarRuns) {
  std::string text = slurp(kSource / "scenarios/wsn_star.toml");
  text.replace(text.find("[plant]\n"), 8, "[plant]\nBu = [[0.0], [1.0]]\n");
  text +=
      "\n[[link]]\nname = \"act\"\nkind = \"network\"\nnetwork = \"wsn\"\nbytes = 16\n"
      "position = [8.0, -6.0, 0.0]\ndesign_pmf = [0.98, 0.02]\n"
      "\n[[actuator]]\nlink = \"act\"\n\n[input]\nkind = \"white\"\nstd = [0.5]\n";
  const fs::path file = dir_ / "wsn_act.toml";
  std::ofstream(file) << text;
  auto run = [&](const std::string& name, const std::string& threads) {
    const Outcome o = ncosim({"run", file.string(), "--out", (dir_ / name).string(), "--runs", "2",
                              "--periods", "300", "--quiet", "--no-timing", "--threads", threads});
    EXPECT_EQ(o.code, 0) << o.output;
  };
  run("t1", "1");
  run("t2", "2");
  EXPECT_EQ(slurp(dir_ / "t1" / "runs.csv"), slurp(dir_ / "t2" / "runs.csv"));
  EXPECT_EQ(slurp(dir_ / "t1" / "links.csv"), slurp(dir_ / "t2" / "links.csv"));
  const auto links = links_column(dir_ / "t1", "link");
  ASSERT_EQ(links.size(), 5U);
  EXPECT_EQ(links.back(), "act");
  const double ratio = std::stod(links_column(dir_ / "t1", "delivered_ratio").back());
  EXPECT_GT(ratio, 0.5);
  EXPECT_LE(ratio, 1.0);
  // The same over 802.11a: the commands arrive (a wifi network carries actuator links too).
  std::string wifi = text;
  wifi.replace(wifi.find("kind = \"lr_wpan\""), 16, "kind = \"wifi\"");
  // At 0 dBm the sensors 20 m away are below what the sink's 802.11 receiver hears (refused).
  wifi.replace(wifi.find("tx_power = 0.0"), 14, "tx_power = 16.0");
  std::ofstream(dir_ / "wifi_act.toml") << wifi;
  const Outcome w =
      ncosim({"run", (dir_ / "wifi_act.toml").string(), "--out", (dir_ / "w").string(), "--runs",
              "2", "--periods", "300", "--quiet", "--no-timing"});
  EXPECT_EQ(w.code, 0) << w.output;
  EXPECT_GT(std::stod(links_column(dir_ / "w", "delivered_ratio").back()), 0.5);
  // A network link is one node: an actuator's cannot be a sensor's too.
  const std::string own = "[[actuator]]\nlink = \"act\"";
  text.replace(text.find(own), own.size(), "[[actuator]]\nlink = \"n1\"");
  std::ofstream(dir_ / "shared.toml") << text;
  const Outcome bad = ncosim({"check", (dir_ / "shared.toml").string()});
  EXPECT_EQ(bad.code, 2) << bad.output;
  EXPECT_NE(bad.output.find(fmt::format(
                "shared.toml:{}: key 'actuator[0].link': expected a link no [[sensor]] or other "
                "[[actuator]] uses: link \"n1\" is a node of a [[network]]",
                line_of(text, "link = \"n1\"\n\n[input]"))),
            std::string::npos)
      << bad.output;
}

TEST_F(NetworkCli, BadInputNamesTheKeyAndItsLine) {
  struct Case {
    std::string from, to;  // the edit
    std::string at;        // the text on the line the message names
    std::string message;
    std::string from2 = "", to2 = "";  // a second edit, when not empty
  };
  const std::vector<Case> cases{
      {"network = \"bus\"", "network = \"lan\"", "network = \"lan\"",
       "key 'link[0].network': expected the name of a [[network]] (\"bus\"), got \"lan\""},
      // A sender on two networks cannot be written: a link names one.
      {"network = \"bus\"", "network = [\"bus\", \"bus\"]", "network = [",
       "key 'link[0].network': expected a string, got an array [\"bus\", \"bus\"]"},
      {"kind = \"csma\"", "kind = \"token_ring\"", "kind = \"token_ring\"",
       "key 'network[0].kind': expected one of \"csma\", \"lr_wpan\", \"wifi\", got "
       "\"token_ring\""},
      {"rate = 1e6", "rate = \"fast\"", "rate = \"fast\"",
       "key 'network[0].rate': expected a number"},
      {"bytes = 64", "bytes = 0", "bytes = 0",
       "key 'link[0].bytes': expected an integer in 1..1500"},
      {"bytes = 64", "bytes = 64\nposition = [1.0, 0.0, 0.0]", "position = [1.0",
       "key 'link[0].position': expected no position: network \"bus\" (kind csma) has none"},
      {"kind = \"csma\"\nrate = 1e6\ndelay = 5e-6", "kind = \"lr_wpan\"", "bytes = 115",
       "key 'link[0].bytes': expected at most 114 bytes, the largest payload of network \"bus\" "
       "(kind lr_wpan), got 115",
       "bytes = 64", "bytes = 115"},
      {"kind = \"csma\"\nrate = 1e6\ndelay = 5e-6", "kind = \"lr_wpan\"", "position = [300.0",
       "key 'link[0].position': expected a node within range of network \"bus\"'s sink (kind "
       "lr_wpan): at 300 m the sink receives -120.99 dBm from it, below the -111.99 dBm it needs "
       "(ns-3's 802.15.4 receiver drops a frame below -5 dB of signal to noise, and its noise "
       "floor "
       "is -106.99 dBm)",
       "bytes = 64", "bytes = 64\nposition = [300.0, 0.0, 0.0]"},
      // Issue 40 part 7: wifi refuses a fixed node its sink cannot hear, as lr_wpan does (ns-3's
      // preamble detection: nothing below -82 dBm).
      {"kind = \"csma\"\nrate = 1e6\ndelay = 5e-6", "kind = \"wifi\"", "position = [300.0",
       "key 'link[0].position': expected a node within range of network \"bus\"'s sink (kind "
       "wifi): at 300 m the sink receives -105.05 dBm from it, below the -82.00 dBm it needs",
       "bytes = 64", "bytes = 64\nposition = [300.0, 0.0, 0.0]"},
      {"[[sensor]]", "[[background]]\nnetwork = \"bus\"\nrate = \"fast\"\n\n[[sensor]]",
       "rate = \"fast\"",
       "key 'background[0].rate': expected a rate in (0, 1e7] packets/s or \"saturated\", got a "
       "string \"fast\""},
      {"[[sensor]]", "[[background]]\nnetwork = \"bus\"\nrate = -1.0\n\n[[sensor]]", "rate = -1.0",
       "key 'background[0].rate': expected a rate in (0, 1e7] packets/s or \"saturated\", got -1"},
      {"[[sensor]]", "[[background]]\nnetwork = \"lan\"\nrate = 5.0\n\n[[sensor]]",
       "network = \"lan\"",
       "key 'background[0].network': expected the name of a [[network]] (\"bus\"), got \"lan\""},
      {"[[sensor]]",
       "[[background]]\nnetwork = \"bus\"\nrate = 5.0\nposition = [1.0, 0.0, 0.0]\n\n[[sensor]]",
       "position = [1.0",
       "key 'background[0].position': expected no position: network \"bus\" (kind csma) has none"},
      {"kind = \"csma\"\nrate = 1e6\ndelay = 5e-6", "kind = \"wifi\"\ndata_mode = \"HtMcs0\"",
       "data_mode = ",
       "key 'network[0].data_mode': expected a data mode of 802.11a (OfdmRate6Mbps, "},
      {"kind = \"csma\"\nrate = 1e6\ndelay = 5e-6", "kind = \"wifi\"\nstandard = \"802.11ac\"",
       "standard = ", "key 'network[0].standard': expected one of"},
      {"link = \"node1\"", "", "name = \"bus\"",
       "key 'network[0].name': expected a network that a sensor's or an actuator's link is a node "
       "of, got \"bus\", which no [[sensor]] or [[actuator]] sends over"},
  };
  const std::string text = slurp(kBoundary);
  for (const auto& c : cases) {
    std::string bad = text;
    ASSERT_NE(bad.find(c.from), std::string::npos) << c.from;
    bad.replace(bad.find(c.from), c.from.size(), c.to);
    if (!c.from2.empty()) bad.replace(bad.find(c.from2), c.from2.size(), c.to2);
    const fs::path file = dir_ / "bad.toml";
    std::ofstream(file) << bad;
    const Outcome o = ncosim({"check", file.string()});
    EXPECT_EQ(o.code, 2) << o.output;
    const std::string where = fmt::format("bad.toml:{}: ", line_of(bad, c.at));
    EXPECT_NE(o.output.find(where + c.message), std::string::npos) << where << c.message << "\n"
                                                                   << o.output;
  }
}

// A design that needs the law of a link whose network decides it during the run, without
// design_pmf: refused before the run, naming the key to give. A design that needs no law runs, and
// links.csv leaves the nominal values empty.
// Issue 40 part 7: a network's work is estimated: 10,000 background nodes or a rate of 1e7
// packets/s on the shipped star (20 runs of 40 s) ran for minutes to hours after a silent check;
// they are refused under the default --max-work, naming the key and the estimate, and pass with
// the limit raised. The star as shipped passes.
TEST_F(NetworkCli, LargeNetworksAreRefusedUnderTheWorkLimit) {
  const std::string star = slurp(kSource / "scenarios/wsn_star.toml");
  ASSERT_EQ(ncosim({"check", (kSource / "scenarios/wsn_star.toml").string()}).code, 0);
  for (const auto& [table, key] : std::vector<std::pair<std::string, std::string>>{
           {"nodes = 10000\nrate = 0.01", "nodes"}, {"rate = 1e7", "rate"}}) {
    const fs::path file = dir_ / "big.toml";
    std::ofstream(file) << star << "\n[[background]]\nnetwork = \"wsn\"\n" << table << "\n";
    const Outcome o = ncosim({"check", file.string()});
    EXPECT_EQ(o.code, 2) << table << ": " << o.output;
    EXPECT_NE(o.output.find("key 'background[0]." + key +
                            "': the networks' simulation needs at least an estimated "),
              std::string::npos)
        << o.output;
    EXPECT_NE(o.output.find("above the work limit of 2000 GFLOP (--max-work"), std::string::npos)
        << o.output;
    // (1e7 packets/s wait in the queue: the memory limit is raised too, see below)
    EXPECT_EQ(ncosim({"check", file.string(), "--max-work", "1e9", "--max-memory", "1e9"}).code, 0)
        << table;
  }
}

TEST_F(NetworkCli, ADesignWithoutTheNetworksLawIsRefusedNamingDesignPmf) {
  std::string text = slurp(kBoundary);
  const std::string law = "design_pmf = [0.0, 1.0]\n";
  text.replace(text.find(law), law.size(), "");
  std::ofstream(dir_ / "open_loop.toml") << text;
  const Outcome ok = ncosim(
      {"run", (dir_ / "open_loop.toml").string(), "--out", (dir_ / "out").string(), "--quiet"});
  EXPECT_EQ(ok.code, 0) << ok.output;
  EXPECT_EQ(links_column(dir_ / "out", "nominal_delay_pmf"), std::vector<std::string>{""});
  const std::string kf = "kind = \"kalman_extended\"\n";
  text.replace(text.find(kf), kf.size(), "kind = \"jump\"\ngrouping = \"S1\"\nhistory = 2\n");
  std::ofstream(dir_ / "jump.toml") << text;
  const Outcome o = ncosim({"check", (dir_ / "jump.toml").string()});
  EXPECT_EQ(o.code, 2) << o.output;
  EXPECT_NE(o.output.find(fmt::format("jump.toml:{}: key 'link[0].design_pmf': a design needs "
                                      "this link's delay law",
                                      line_of(text, "[[link]]"))),
            std::string::npos)
      << o.output;
}

}  // namespace
