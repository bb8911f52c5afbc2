// tests/conformance/conformance_test.cc — every registered kind through the same checks
// (as ns-3 runs one events test against every scheduler). A new kind must add its minimal
// table to the maps below, or KindsHaveAConformanceEntry fails.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>

#include "sim/campaign.h"
#include "sim/output.h"
#include "sim/registries.h"
#include "test_util.h"

namespace ncosim::sim {
namespace {

const std::map<std::string, std::string> kEstimators{
    {"jump", "grouping = \"S3\"\nhistory = 2\nmax_delay = 1"},
    {"kalman_extended", "max_delay = 1"},
    {"open_loop", "max_delay = 1"},
    {"imm", "mode_prior = \"stationary\""},
    {"mode_io", "mode_prior = \"uniform\"\nstartup = \"prior_mean\""},
    {"mode_ss", "mode_prior = \"uniform\""},
    {"kalman_buffer", "buffer = 2"},
    {"static_buffer", "buffer = 2"},
    {"sod_kalman", "W = 0.01\nvirtual_variance_factor = 0.3333"},
    {"sod_jump", "w_rms = 0.1"},
};

// Kinds without max_delay: the misspelt key of the unknown-key test, and its correct spelling.
const std::map<std::string, std::pair<std::string, std::string>> kMisspelt{
    {"imm", {"mode_priorr = \"uniform\"", "mode_prior"}},
    {"mode_io", {"mode_priorr = \"uniform\"", "mode_prior"}},
    {"mode_ss", {"mode_priorr = \"uniform\"", "mode_prior"}},
    {"sod_kalman", {"virtual_variance_factr = 0.3", "virtual_variance_factor"}},
    {"sod_jump", {"virtual_nois = \"delta2\"", "virtual_noise"}},
};

// Mode estimators need modes: their scenarios get an [[actuator]] on the same link kind.
bool is_mode_kind(const std::string& k) { return k == "imm" || k == "mode_io" || k == "mode_ss"; }

const std::map<std::string, std::string> kLinks{
    {"delay", "pmf = [0.5, 0.3]"},
    {"bernoulli", "loss = 0.2\ndelay = 1"},
    {"negative_binomial", "successes = 3\np = 0.5\nloss = 0.1"},
    {"arrival_cdf", "cdf = [0.1, 0.5]\ntail = 0.8"},
    {"gilbert_elliott", "p_good_to_bad = 0.1\np_bad_to_good = 0.3"},
    {"markov", "transition = [[0.9, 0.1], [0.5, 0.5]]\nloss = [0.0, 1.0]"},
    {"trace", "file = \"TRACE\""},
    {"sumo_distance", "sender = \"leader\"\nreceiver = \"follower\""},
};

const std::map<std::string, std::string> kPlants{
    {"lti", "A = [[0.8821, -0.0351], [-0.0351, 0.7347]]\nBu = [[-0.3359], [0.3466]]\nW = [[0.01, 0], [0, 0.01]]"},
    {"lti_continuous", "Ac = [[-0.1, 1.0], [0.0, -0.3]]\nBc = [[0.0], [1.0]]\nWc = [[0.01, 0], [0, 0.01]]"},
    {"jump_linear",
     "A = [[0.8821, -0.0351], [-0.0351, 0.7347]]\nBu = [[-0.3359], [0.3466]]\nW = [[0.01, 0], [0, 0.01]]\n"
     "transition = [[0.9, 0.1], [0.3, 0.7]]\n[[plant.mode]]\n[[plant.mode]]\nA = [[0.5, 0.0], [0.1, 0.6]]\n"
     "W = [[0.05, 0], [0, 0.05]]"},
    {"transfer_function", "num = [1.0]\nden = [1.0, 0.5, 0.1]\nW = 0.01"},
    {"sumo_vehicle", "vehicle = \"leader\"\nq = 1.0"},
};

// Kinds that need a [sumo] table (SUMO vehicles): exercised by tests/sumo on a generated road,
// skipped by the generic loops below.
bool needs_sumo(const std::string& kind) { return kind.starts_with("sumo_"); }

const std::map<std::string, std::string> kInputs{
    {"none", ""},
    {"white", "std = 1.0"},
    {"state_feedback", "K = [[0.1, 0.1]]\nsource = \"plant\""},
    {"relay", "level = 0.5\ndead_zone = 0.2\noutputs = [0]\nsees = \"measured\""},
    {"pi", "kp = 0.1\nki = 0.05\nb = 0.7\nu_min = -1.0\nu_max = 1.0\nreference = {kind = \"square\", low = 0.0, high = 1.0, period = 50.0}"},
};

struct TempDir {
  std::filesystem::path path;
  TempDir() {
    path = std::filesystem::temp_directory_path() /
           ("ncosim_conf_" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()) + "_" +
            std::to_string(reinterpret_cast<std::uintptr_t>(this)));
    std::filesystem::create_directories(path);
  }
  ~TempDir() { std::filesystem::remove_all(path); }
};

// A small scenario: the given plant, input, one link kind for both sensors, and estimators.
std::string scenario_text(const std::string& plant_kind, const std::string& input_kind,
                          const std::string& link_kind, const std::vector<std::string>& est_kinds,
                          const std::string& extra_estimator_key = "") {
  std::string s = "[run]\nperiods = 3000\nwarmup = 100\nruns = 3\nseed = 7\n\n";
  s += "[plant]\nkind = \"" + plant_kind + "\"\n" + kPlants.at(plant_kind) + "\n\n";
  s += "[input]\nkind = \"" + input_kind + "\"\n" + kInputs.at(input_kind) + "\n\n";
  s += "[[link]]\nname = \"net\"\nkind = \"" + link_kind + "\"\n" + kLinks.at(link_kind) + "\n\n";
  s += "[[sensor]]\nC = [[1.0, 0.0]]\nR = [[0.01]]\nlink = \"net\"\n\n";
  s += "[[sensor]]\nC = [[0.0, 1.0]]\nR = [[0.01]]\nlink = \"net\"\n\n";
  bool modes = false;
  for (const auto& k : est_kinds) modes = modes || is_mode_kind(k);
  if (modes) s += "[[actuator]]\nlink = \"net\"\non_loss = \"hold\"\n\n";
  for (const auto& k : est_kinds) {
    s += "[[estimator]]\nname = \"" + k + "\"\nkind = \"" + k + "\"\n" + kEstimators.at(k) + "\n" +
         extra_estimator_key + "\n";
  }
  return s;
}

std::string write_scenario(const TempDir& dir, const std::string& text) {
  {
    std::ofstream trace(dir.path / "trace.csv");
    trace << "seq,delay\n";
    for (int i = 0; i < 25000; ++i) trace << i << "," << (i % 5 == 4 ? "" : std::to_string(i % 2)) << "\n";
  }
  std::string t = text;
  for (std::size_t p; (p = t.find("TRACE")) != std::string::npos;) t.replace(p, 5, "trace.csv");
  const auto file = (dir.path / "s.toml").string();
  std::ofstream(file) << t;
  return file;
}

template <class R>
void expect_entries(const R& registry, const std::map<std::string, std::string>& table, const char* what) {
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
    if (needs_sumo(link.name)) continue;
    TempDir dir;
    const auto file = write_scenario(dir, scenario_text("lti", "white", link.name, all_estimators()));
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
      for (std::size_t run = 0; run < a.runs.size(); ++run) EXPECT_EQ(a.runs[run][e].sse, b.runs[run][e].sse);
    }
  }
}

TEST(Conformance, EveryKindRejectsAnUnknownKeyWithADidYouMean) {
  TempDir dir;
  for (const auto& k : all_estimators()) {
    const auto bad = kMisspelt.count(k) ? kMisspelt.at(k) : std::make_pair(std::string("max_delayy = 1"), std::string("max_delay"));
    const auto file = write_scenario(dir, scenario_text("lti", "none", "delay", {k}, bad.first));
    try {
      testing::load_one(file);
      ADD_FAILURE() << k << " accepted an unknown key";
    } catch (const ScenarioError& e) {
      EXPECT_NE(std::string(e.what()).find("did you mean '" + bad.second + "'"), std::string::npos) << e.what();
    }
  }
  for (const auto& l : link_registry().entries()) {
    if (needs_sumo(l.name)) continue;
    std::string text = scenario_text("lti", "none", l.name, {"open_loop"});
    text.replace(text.find("[[sensor]]"), 0, "bogus_key = 1\n\n");
    const auto file = write_scenario(dir, text);
    EXPECT_THROW(testing::load_one(file), ScenarioError) << l.name;
  }
}

TEST(Conformance, EveryLinkHonoursItsMarginalLaw) {
  // For each kind: delay_pmf entries in [0, 1] summing to at most 1 - loss (+1e-12), every
  // transmit is kLost or a delay >= 0, clones replay identically from the same stream, and
  // the empirical loss rate over 20000 packets is within 4.5 binomial sigmas of loss_probability().
  for (const auto& l : link_registry().entries()) {
    if (needs_sumo(l.name)) continue;
    TempDir dir;
    const auto file = write_scenario(dir, scenario_text("lti", "none", l.name, {"open_loop"}));
    auto sc = testing::load_one(file);
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
    Rng ra = make_stream(1, 0, 0), rb = make_stream(1, 0, 0);
    a->reset(ra);
    b->reset(rb);
    const int n = 20000;
    int lost = 0;
    for (int i = 0; i < n; ++i) {
      const auto da = a->transmit(ra);
      ASSERT_EQ(da, b->transmit(rb));
      ASSERT_TRUE(da == models::kLost || da >= 0);
      lost += da == models::kLost;
    }
    const double sigma = std::sqrt(n * loss * (1 - loss)) + 1e-9;
    EXPECT_LT(std::abs(lost - n * loss), 4.5 * sigma + 1) << lost << " lost of " << n << ", expected " << n * loss;
  }
}

TEST(Conformance, EveryPlantAndInputKindBuildsAndRuns) {
  for (const auto& p : plant_registry().entries()) {
    if (needs_sumo(p.name)) continue;
    for (const auto& in : input_registry().entries()) {
      TempDir dir;
      const auto file = write_scenario(dir, scenario_text(p.name, in.name, "bernoulli", {"kalman_extended"}));
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

}  // namespace
}  // namespace ncosim::sim
