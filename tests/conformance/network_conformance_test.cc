// tests/conformance/network_conformance_test.cc — every registered network kind ([[network]] kind,
// network/backend.h) through the same checks: a table with an unknown key is refused with a
// did-you-mean; its runs keep the NetworkRun contract (every packet sent gets exactly one fate,
// never before it was sent nor after the instant advanced to, the same twice from the same seed
// and run); and a campaign over it finishes with every row ok, the same numbers twice, a node's
// stack counters in links.csv and no more deliveries than packets sent. A new kind must add its
// minimal table to kNetworks (conformance/fixtures.h), or KindsHaveAConformanceEntry fails.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <string>
#include <vector>

#include "conformance/fixtures.h"
#include "network/networks.h"
#include "network/ns3/ns3_network.h"
#include "network/worker.h"
#include "sim/analysis/output.h"
#include "sim/run/campaign.h"
#include "sim/scenario/registries.h"
#include "test_util.h"

namespace ncosim::sim {
namespace {

using namespace conformance;  // NOLINT: the suite's fixtures

TEST(Conformance, NetworkKindsHaveAConformanceEntryAndHelp) {
  for (const auto& e : network_registry().entries()) {
    EXPECT_TRUE(kNetworks.count(e.name))
        << "network kind '" << e.name << "' has no conformance entry";
    EXPECT_FALSE(e.help.empty()) << "network kind '" << e.name << "' has no help line";
  }
}

// A scenario whose two sensors send every 20 ms over two links that are nodes of one [[network]]
// of `kind` (`extra`: more keys of its table).
std::string network_scenario(const std::string& kind, const std::string& extra = "") {
  std::string s = "[run]\nperiods = 200\nwarmup = 20\nruns = 2\nseed = 11\nperiod = 0.02\n\n";
  s += "[plant]\n" + kPlants.at("lti") + "\n\n";
  s += "[[network]]\nname = \"net\"\nkind = \"" + kind + "\"\n" + kNetworks.at(kind) + "\n" +
       extra + "\n";
  const char* positions[] = {"[3.0, 0.0, 0.0]", "[0.0, 4.0, 0.0]"};
  for (int n = 0; n < 2; ++n) {
    s += fmt::format("[[link]]\nname = \"n{}\"\nkind = \"network\"\nnetwork = \"net\"\n", n);
    s += kind == "csma" ? "\n" : fmt::format("position = {}\n\n", positions[n]);
  }
  s += "[[sensor]]\nC = [[1.0, 0.0]]\nR = [[0.01]]\nlink = \"n0\"\n\n";
  s += "[[sensor]]\nC = [[0.0, 1.0]]\nR = [[0.01]]\nlink = \"n1\"\n\n";
  s += "[[estimator]]\nname = \"Kalman\"\nkind = \"kalman_extended\"\nmax_delay = 3\n\n";
  s += "[[estimator]]\nname = \"open loop\"\nkind = \"open_loop\"\n";
  return s;
}

bool runnable(const std::string& kind) {
  (void)kind;
  return network::have_ns3();  // every built-in kind is an ns-3 kind
}

TEST(Conformance, EveryNetworkKindRejectsAnUnknownKeyWithADidYouMean) {
  for (const auto& e : network_registry().entries()) {
    if (!runnable(e.name)) continue;
    SCOPED_TRACE(e.name);
    TempDir dir;
    const auto& keys = e.keys.list();
    ASSERT_FALSE(keys.empty());
    const std::string key = keys.front().name();
    const auto file = write_scenario(dir, network_scenario(e.name, key + "x = 1"));
    try {
      testing::load_one(file);
      ADD_FAILURE() << e.name << " accepted an unknown key";
    } catch (const config::ScenarioError& err) {
      EXPECT_NE(std::string(err.what()).find("did you mean '" + key + "'"), std::string::npos)
          << err.what();
    }
  }
}

// The NetworkRun contract, run here (network::start_here): ten packets of each of two nodes, five
// at a time; every fate names a packet sent, once, at or after its send time and at or before the
// instant advanced to; a second run of the same seed and run gives the same fates.
std::vector<network::Fate> contract_run(const Scenario& sc, std::uint64_t run) {
  std::vector<const network::NetworkDesign*> designs;
  for (const auto& n : sc.networks) designs.push_back(n.design.get());
  std::vector<network::Sender> senders;
  for (const auto& l : sc.links) {
    const auto* a = l.link->network_attachment();
    senders.push_back(network::Sender{a->network, a->bytes, a->x, a->y, a->z});
  }
  auto r = network::start_here(designs, senders, sc.run.seed, run);
  std::vector<network::Fate> all;
  std::map<std::uint64_t, std::int64_t> sent;
  constexpr std::int64_t kStep = 20'000'000;
  for (int k = 0; k < 4; ++k) {
    for (std::uint64_t i = 0; i < 5; ++i) {
      const std::uint64_t id = 100 * k + i;
      sent[id] = k * kStep;
      r->send(static_cast<int>(i % 2), id, k * kStep);
    }
    const std::size_t before = all.size();
    r->advance_to(k * kStep, all);
    for (std::size_t f = before; f < all.size(); ++f) {
      EXPECT_LE(all[f].time, k * kStep) << "a fate after the instant advanced to";
    }
  }
  r->advance_to(60 * kStep, all);
  std::map<std::uint64_t, int> fates;
  for (const auto& f : all) {
    EXPECT_TRUE(sent.count(f.id)) << "a fate of packet " << f.id << ", never sent";
    if (!sent.count(f.id)) continue;
    EXPECT_GE(f.time, sent[f.id]);
    EXPECT_EQ(f.sender, static_cast<int>((f.id % 100) % 2));
    ++fates[f.id];
  }
  for (const auto& [id, t] : sent) EXPECT_EQ(fates[id], 1) << "packet " << id;
  return all;
}

TEST(Conformance, EveryNetworkKindKeepsTheRunContract) {
  for (const auto& e : network_registry().entries()) {
    if (!runnable(e.name)) continue;
    SCOPED_TRACE(e.name);
    TempDir dir;
    auto sc = testing::load_one(write_scenario(dir, network_scenario(e.name)));
    const auto a = contract_run(*sc, 1);
    const auto b = contract_run(*sc, 1);
    ASSERT_EQ(a.size(), b.size());
    for (std::size_t f = 0; f < a.size(); ++f) {
      EXPECT_EQ(a[f].id, b[f].id);
      EXPECT_EQ(a[f].time, b[f].time);
      EXPECT_EQ(a[f].drop, b[f].drop);
    }
  }
}

TEST(Conformance, EveryNetworkKindRunsACampaignTwiceTheSame) {
  network::set_worker_executable(NCOSIM_BINARY);
  for (const auto& e : network_registry().entries()) {
    if (!runnable(e.name)) continue;
    SCOPED_TRACE(e.name);
    TempDir dir;
    auto sc = testing::load_one(write_scenario(dir, network_scenario(e.name)));
    CampaignOptions opt;
    opt.time_estimators = false;
    opt.threads = 2;
    const auto a = run_campaign(*sc, opt);
    const auto b = run_campaign(*sc, opt);
    for (const auto& row : summarise(*sc, a, {})) {
      EXPECT_EQ(row.status, "ok") << row.estimator;
      ASSERT_TRUE(row.mse.has_value());
      EXPECT_TRUE(std::isfinite(*row.mse));
    }
    for (std::size_t r = 0; r < a.runs.size(); ++r) {
      for (std::size_t est = 0; est < a.runs[r].size(); ++est)
        EXPECT_EQ(a.runs[r][est].sse, b.runs[r][est].sse);
      for (const auto& flow : a.link_runs[r]) {
        ASSERT_TRUE(flow.stack.has_value());
        EXPECT_LE(flow.delivered, flow.sent);
        EXPECT_GE(flow.stack->attempts, flow.delivered);
      }
    }
  }
}

}  // namespace
}  // namespace ncosim::sim
