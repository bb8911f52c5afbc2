// tests/sim/embedding_test.cc — what a program that embeds the command line uses (the Python
// package, python/): a scenario held in memory (ScenarioText), kinds added while the program runs
// (add_extension_now), the progress observer, and errors of a "<dict>" scenario without a line.
#include <gtest/gtest.h>

#include <stdexcept>
#include <string>
#include <vector>

#include "config/config.h"
#include "sim/run/progress.h"
#include "sim/scenario/extensions.h"
#include "sim/scenario/registries.h"
#include "sim/scenario/scenario.h"

namespace {

using ncosim::sim::ScenarioText;

const char* kScenario = R"(
[run]
runs = 2
periods = 50
[plant]
kind = "lti"
A = [[0.9]]
Bw = [[1.0]]
W = [[1.0]]
[[sensor]]
C = [[1.0]]
R = [[1.0]]
[[estimator]]
kind = "open_loop"
)";

TEST(Embedding, AScenarioTextStandsForItsNameWhileItLives) {
  {
    const ScenarioText text("<string>", kScenario);
    const auto loaded = ncosim::sim::load_cases("<string>", {"run.runs=3"});
    EXPECT_EQ(loaded.cases.size(), 1U);
    EXPECT_EQ(loaded.cases.front().scenario->run.runs, 3);
    EXPECT_THROW(ScenarioText("<string>", "x = 1"), std::logic_error);  // one per name
  }
  // Gone with it: the name is a file name again (none exists).
  EXPECT_THROW(ncosim::sim::load_cases("<string>", {}), ncosim::config::ScenarioError);
}

TEST(Embedding, ADictsErrorsNameTheKeyWithoutALine) {
  std::string bad = kScenario;
  bad.replace(bad.find("A = [[0.9]]"), 11, "A = [[0.9, 1.0]]");
  for (const std::string name : {"<dict>", "s.toml"}) {
    const ScenarioText text(name, bad);
    try {
      ncosim::sim::load_cases(name, {});
      FAIL() << "a non-square A was accepted";
    } catch (const ncosim::config::ScenarioError& e) {
      const std::string what = e.what();
      if (name == "<dict>") {
        EXPECT_EQ(what.rfind("<dict>: key 'plant.A': ", 0), 0U) << what;
      } else {
        EXPECT_EQ(what.rfind("s.toml:7: key 'plant.A': ", 0), 0U) << what;
      }
    }
  }
}

TEST(Embedding, KindsAddedWhileTheProgramRuns) {
  const auto& registry = ncosim::sim::estimator_registry();  // built before the addition
  const auto add = [](const std::string& name) {
    ncosim::sim::add_extension_now([name](ncosim::sim::Registries& r) {
      r.estimators.add(name, "a test kind",
                       [](const ncosim::config::Table&, const ncosim::est::Model&) {
                         return std::unique_ptr<ncosim::est::EstimatorDesign>();
                       });
    });
  };
  EXPECT_EQ(registry.find("embedding_test_kind"), nullptr);
  add("embedding_test_kind");
  ASSERT_NE(registry.find("embedding_test_kind"), nullptr);
  const auto count = registry.entries().size();
  EXPECT_THROW(add("embedding_test_kind"), std::logic_error);  // a name that exists
  EXPECT_THROW(add("kalman_extended"), std::logic_error);
  EXPECT_EQ(registry.entries().size(), count);  // and nothing changed
  EXPECT_THROW(ncosim::sim::add_extension([](ncosim::sim::Registries&) {}), std::logic_error);
}

TEST(Embedding, TheProgressObserverSeesEveryRunAndAFinalCall) {
  std::vector<ncosim::sim::CampaignProgress::Snapshot> seen;
  {
    ncosim::sim::CampaignProgress p(
        [&seen](const ncosim::sim::CampaignProgress::Snapshot& s) { seen.push_back(s); });
    p.set_total(10, 4, false);
    p.set_case(1, 3);
    p.start();
    p.add_done(6);
    p.finish();
  }
  ASSERT_FALSE(seen.empty());
  const auto& last = seen.back();
  EXPECT_TRUE(last.final);
  EXPECT_EQ(last.done, 10U);
  EXPECT_EQ(last.total, 10U);
  EXPECT_EQ(last.stored, 4U);
  EXPECT_EQ(last.case_index, 1U);
  EXPECT_EQ(last.cases, 3U);
  for (std::size_t i = 0; i + 1 < seen.size(); ++i) EXPECT_FALSE(seen[i].final);
}

}  // namespace
