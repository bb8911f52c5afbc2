// tests/conformance/conformance_test.cc — every registered kind through the same checks
// (as ns-3 runs one events test against every scheduler). A new kind must add its minimal
// table to the maps of conformance/fixtures.h, or KindsHaveAConformanceEntry fails.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>

#include "conformance/fixtures.h"
#include "sim/analysis/output.h"
#include "sim/run/campaign.h"
#include "sim/scenario/registries.h"
#include "test_util.h"

namespace ncosim::sim {
namespace {

using namespace conformance;  // NOLINT: the suite's fixtures

template <class R>
void expect_entries(const R& registry, const std::map<std::string, std::string>& table,
                    const char* what) {
  for (const auto& e : registry.entries()) {
    EXPECT_TRUE(table.count(e.name)) << what << " kind '" << e.name << "' has no conformance entry";
    EXPECT_FALSE(e.help.empty()) << what << " kind '" << e.name << "' has no help line";
  }
}

TEST(Conformance, KindsHaveAConformanceEntryAndHelp) {
  expect_entries(estimator_registry(), kEstimators, "estimator");
  expect_entries(link_registry(), kLinks, "link");
  expect_entries(plant_registry(), kPlants, "plant");
  expect_entries(input_registry(), kInputs, "input");
  expect_entries(send_policy_registry(), kSendPolicies, "send policy");
}

std::vector<std::string> all_estimators() {
  std::vector<std::string> v;
  for (const auto& e : estimator_registry().entries()) v.push_back(e.name);
  return v;
}

TEST(Conformance, EveryEstimatorRunsFiniteDeterministicAndBeatsNothingWithoutData) {
  // Every estimator on every link kind: finite mse, status ok, the same numbers twice, FLOPs
  // reported, delivered_ratio in [0, 1], and no estimator worse than open loop beyond 5%
  // (open loop uses no data; on a stable plant every estimator that uses data must do at
  // least as well up to Monte Carlo noise, here bounded loosely since the runs are short).
  for (const auto& link : link_registry().entries()) {
    if (exercised_elsewhere(link.name)) continue;
    TempDir dir;
    const auto file =
        write_scenario(dir, scenario_text("lti", "white", link.name, all_estimators()));
    auto sc = testing::load_one(file);
    CampaignOptions opt;
    opt.time_estimators = false;
    const auto a = run_campaign(*sc, opt);
    const auto b = run_campaign(*sc, opt);
    const auto rows = summarise(*sc, a, {});
    double open_loop = 0.0;
    for (const auto& r : rows) {
      if (r.kind == "open_loop") open_loop = r.mse.value_or(0.0);
    }
    for (std::size_t e = 0; e < rows.size(); ++e) {
      const auto& r = rows[e];
      SCOPED_TRACE(r.kind + " on link " + link.name);
      EXPECT_EQ(r.status, "ok");
      ASSERT_TRUE(r.mse.has_value());
      EXPECT_TRUE(std::isfinite(*r.mse));
      EXPECT_TRUE(r.flops_per_period.has_value());
      ASSERT_TRUE(r.delivered_ratio.has_value());
      EXPECT_GE(*r.delivered_ratio, 0.0);
      EXPECT_LE(*r.delivered_ratio, 1.0);
      EXPECT_LE(*r.mse, 1.05 * open_loop);
      for (std::size_t run = 0; run < a.runs.size(); ++run)
        EXPECT_EQ(a.runs[run][e].sse, b.runs[run][e].sse);
    }
  }
}

TEST(Conformance, EveryKindRejectsAnUnknownKeyWithADidYouMean) {
  TempDir dir;
  for (const auto& k : all_estimators()) {
    const auto bad = kMisspelt.count(k)
                         ? kMisspelt.at(k)
                         : std::make_pair(std::string("max_delayy = 1"), std::string("max_delay"));
    const auto file = write_scenario(dir, scenario_text("lti", "none", "delay", {k}, bad.first));
    try {
      testing::load_one(file);
      ADD_FAILURE() << k << " accepted an unknown key";
    } catch (const config::ScenarioError& e) {
      EXPECT_NE(std::string(e.what()).find("did you mean '" + bad.second + "'"), std::string::npos)
          << e.what();
    }
  }
  for (const auto& l : link_registry().entries()) {
    if (exercised_elsewhere(l.name)) continue;
    std::string text = scenario_text("lti", "none", l.name, {"open_loop"});
    text.replace(text.find("[[sensor]]"), 0, "bogus_key = 1\n\n");
    const auto file = write_scenario(dir, text);
    EXPECT_THROW(testing::load_one(file), config::ScenarioError) << l.name;
  }
}

// The fixtures' small scenario with both sensors on one link of `kind` (read at load: the
// temporary folder, with a trace's file, can go once the scenario is loaded).
auto link_scenario(const std::string& kind) {
  TempDir dir;
  return testing::load_one(write_scenario(dir, scenario_text("lti", "none", kind, {"open_loop"})));
}

TEST(Conformance, EveryLinkHonoursItsMarginalLaw) {
  // For each kind: delay_pmf entries in [0, 1] summing to at most 1 - loss (+1e-12), every
  // transmit is kLost or a delay >= 0, clones replay identically from the same stream, and
  // the empirical loss rate over 20000 packets is within 4.5 binomial sigmas of loss_probability().
  for (const auto& l : link_registry().entries()) {
    if (exercised_elsewhere(l.name)) continue;
    auto sc = link_scenario(l.name);
    const models::Link& link = *sc->links.front().link;
    SCOPED_TRACE(l.name);
    const auto pmf = link.delay_pmf(40);
    double sum = 0.0;
    for (double p : pmf) {
      EXPECT_GE(p, 0.0);
      EXPECT_LE(p, 1.0);
      sum += p;
    }
    const double loss = link.loss_probability();
    EXPECT_LE(sum, 1.0 - loss + 1e-12);
    auto a = link.clone(), b = link.clone();
    kernel::Rng ra = kernel::make_stream(1, 0, 0), rb = kernel::make_stream(1, 0, 0);
    a->reset(ra);
    b->reset(rb);
    const int n = 20000;
    int lost = 0;
    for (int i = 0; i < n; ++i) {
      a->advance(i, ra);  // one packet per period, as a sensor sending every period
      b->advance(i, rb);
      const auto da = a->transmit(ra);
      ASSERT_EQ(da, b->transmit(rb));
      ASSERT_TRUE(da == models::kLost || da >= 0);
      lost += da == models::kLost;
    }
    const double sigma = std::sqrt(n * loss * (1 - loss)) + 1e-9;
    EXPECT_LT(std::abs(lost - n * loss), 4.5 * sigma + 1)
        << lost << " lost of " << n << ", expected " << n * loss;
  }
}

TEST(Conformance, EveryLinkThatClaimsTheDesignModelLosesPacketsIndependently) {
  // A kind whose loss_model_of() is kIndependent is taken by summary.csv's model_check for the
  // designs' model (sim/analysis/validity.cc): its consecutive packets must be lost independently.
  // Over n = 20000 packets the count of consecutive lost pairs must be within 4.5 sigmas of (n - 1)
  // p^2 (sigma of a sum of overlapping pair indicators: variance (n - 1) p^2 (1 - p^2) + 2 (n - 2)
  // (p^3 - p^4)). The fixtures' dependent kinds break this bound (the bursty chains above it, the
  // trace, which never loses two in a row, below it), so the check can tell them apart: at least
  // one kind must fail it and not claim.
  int dependent_seen = 0;
  for (const auto& l : link_registry().entries()) {
    if (exercised_elsewhere(l.name)) continue;
    auto sc = link_scenario(l.name);
    const models::Link& proto = *sc->links.front().link;
    SCOPED_TRACE(l.name);
    auto link = proto.clone();
    kernel::Rng rng = kernel::make_stream(7, 0, 0);
    link->reset(rng);
    const int n = 20000;
    int pairs = 0;
    bool previous = false;
    for (int i = 0; i < n; ++i) {
      link->advance(i, rng);
      const bool lost = link->transmit(rng) == models::kLost;
      pairs += lost && previous;
      previous = lost;
    }
    const double p = proto.loss_probability();
    const double m = n - 1.0;
    const double sigma =
        std::sqrt(m * p * p * (1 - p * p) + 2.0 * (m - 1.0) * (p * p * p - p * p * p * p)) + 1e-9;
    const bool independent_looking = std::abs(pairs - m * p * p) < 4.5 * sigma + 1;
    if (models::loss_model_of(proto) == models::LinkReporting::LossModel::kIndependent) {
      EXPECT_TRUE(independent_looking)
          << pairs << " consecutive losses, expected " << m * p * p << " +- " << sigma;
    } else if (!independent_looking) {
      ++dependent_seen;
    }
  }
  EXPECT_GE(dependent_seen, 1);
}

TEST(Conformance, EveryPlantAndInputKindBuildsAndRuns) {
  for (const auto& p : plant_registry().entries()) {
    if (needs_sumo(p.name)) continue;
    for (const auto& in : input_registry().entries()) {
      TempDir dir;
      const auto file =
          write_scenario(dir, scenario_text(p.name, in.name, "bernoulli", {"kalman_extended"}));
      auto sc = testing::load_one(file);
      SCOPED_TRACE(p.name + " with input " + in.name);
      EXPECT_EQ(sc->model.plant.A.rows(), 2);
      Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(sc->model.plant.W);
      EXPECT_GE(es.eigenvalues().minCoeff(), -1e-15);
      CampaignOptions opt;
      opt.time_estimators = false;
      const auto rows = summarise(*sc, run_campaign(*sc, opt), {});
      EXPECT_EQ(rows.front().status, "ok");
    }
  }
}

TEST(Conformance, EverySendPolicyDecidesAndKeepsTheRunDeterministic) {
  // Every policy on both sensors: the run completes with finite errors, sends at most what was
  // taken (all of it when the policy says it sends every sample), repeats bit for bit, and names
  // itself in transmissions.csv.
  for (const auto& p : send_policy_registry().entries()) {
    SCOPED_TRACE("send policy " + p.name);
    TempDir dir;
    std::string text = scenario_text("lti", "white", "bernoulli", {"kalman_extended"});
    const std::string keys = "policy = \"" + p.name + "\"\n" + kSendPolicies.at(p.name) + "\n";
    for (std::size_t at = text.find("[[sensor]]\n"); at != std::string::npos;
         at = text.find("[[sensor]]\n", at + 1)) {
      text.insert(at + 11, keys);
    }
    auto sc = testing::load_one(write_scenario(dir, text));
    ASSERT_EQ(sc->model.sensors.size(), 2u);
    EXPECT_EQ(sc->model.sensors[0].spec.policy->name(), p.name);
    CampaignOptions opt;
    opt.time_estimators = false;
    const auto a = run_campaign(*sc, opt);
    const auto b = run_campaign(*sc, opt);
    for (std::size_t r = 0; r < a.runs.size(); ++r) {
      const auto& m = a.runs[r][0];
      EXPECT_TRUE(std::isfinite(m.sse)) << "run " << r;
      EXPECT_EQ(m.sse, b.runs[r][0].sse) << "run " << r;
      for (std::size_t s = 0; s < 2; ++s) {
        EXPECT_GT(m.sensor_taken[s], 0);
        EXPECT_LE(m.sensor_sent[s], m.sensor_taken[s]);
        if (sc->model.sensors[s].spec.policy->sends_every_sample()) {
          EXPECT_EQ(m.sensor_sent[s], m.sensor_taken[s]);
        }
      }
    }
    const std::string csv = transmissions_csv({}, {{}}, {sc.get()}, {&a});
    EXPECT_NE(csv.find("," + p.name + ","), std::string::npos) << csv;
  }
}

}  // namespace
}  // namespace ncosim::sim
