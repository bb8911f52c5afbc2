// tests/sim/ladder_scenario_test.cc — what `ncosim ladder` writes without a network
// (sim/cmd/ladder_scenario.h, sim/cmd/ladder_report.h): the scenario text keeps the file's order
// and values (it parses back to the same document), drops and replaces what it is told, quotes
// what TOML needs, rebases relative input paths; a row is inside the band only when compare's
// interval is.
#include "sim/cmd/ladder_scenario.h"

#include <gtest/gtest.h>
#include <toml++/toml.h>

#include "sim/cmd/ladder_report.h"

namespace ncosim::sim {
namespace {

const char* kText = R"(# a comment
title = "a \"quoted\" title"
[run]
periods = 200
period = 0.02
runs = 4

[plant]
A = [[1.0, 0.1], [0.0, 0.8]]

[[network]]
name = "wsn"
kind = "lr_wpan"

[[link]]
name = "n1"
kind = "network"
network = "wsn"
position = [20.0, 0.0, 0.0]

[[link]]
name = "tr"
kind = "trace"
file = "data/t.csv"
"odd key" = { x = 1, "y z" = true }

[[sensor]]
name = "s"
link = "n1"
)";

TEST(LadderScenario, TheTextKeepsTheFileOrderAndParsesBackToTheSameDocument) {
  const toml::table doc = ladder_document("s.toml", kText, {}, 0, 0, std::nullopt);
  const std::string text = scenario_text(doc, "s.toml", {}, {});
  const toml::table back = toml::parse(text);
  EXPECT_EQ(back, doc) << text;
  // The file's order: [run] before [plant] before [[network]] before [[link]] ...
  EXPECT_LT(text.find("[run]"), text.find("[plant]"));
  EXPECT_LT(text.find("[plant]"), text.find("[[network]]"));
  EXPECT_LT(text.find("[[network]]"), text.find("[[link]]"));
  EXPECT_LT(text.find("[[link]]"), text.find("[[sensor]]"));
  EXPECT_LT(text.find("periods = 200"), text.find("period = 0.02"));
  EXPECT_NE(text.find("title = \"a \\\"quoted\\\" title\""), std::string::npos) << text;
  EXPECT_NE(text.find("\"odd key\" = { x = 1, \"y z\" = true }"), std::string::npos) << text;
  EXPECT_NE(text.find("period = 0.02\n"), std::string::npos) << text;  // shortest, not 0.0200..
}

TEST(LadderScenario, OptionsApplyAndTheSurrogateDropsTheNetworkAndReplacesItsLinks) {
  const toml::table doc =
      ladder_document("s.toml", kText, {"plant.A=[[0.5]]"}, 10, 300, std::uint64_t{7});
  const std::string text =
      scenario_text(doc, "s.toml", {{0, "[[link]]\nname = \"n1\"\nkind = \"ideal\"\n"}},
                    {"network", "background"});
  const toml::table back = toml::parse(text);
  EXPECT_EQ(back["run"]["runs"].value<std::int64_t>(), 10);
  EXPECT_EQ(back["run"]["periods"].value<std::int64_t>(), 300);
  EXPECT_EQ(back["run"]["seed"].value<std::int64_t>(), 7);
  EXPECT_EQ(back["plant"]["A"][0][0].value<double>(), 0.5);
  EXPECT_FALSE(back.contains("network")) << text;
  ASSERT_EQ(back["link"].as_array()->size(), 2U) << text;
  EXPECT_EQ(back["link"][0]["kind"].value<std::string>(), "ideal");
  EXPECT_EQ(back["link"][1]["kind"].value<std::string>(), "trace");  // the others stay
}

// Links written as an inline array (or set so by --set) are [[link]] tables like any others:
// the surrogate replaces them too.
TEST(LadderScenario, AnInlineArrayOfLinksIsReplacedToo) {
  const toml::table doc = ladder_document(
      "s.toml", kText, {"link=[{name = \"n1\", kind = \"network\", network = \"wsn\"}]"}, 0, 0,
      std::nullopt);
  const std::string text = scenario_text(
      doc, "s.toml", {{0, "[[link]]\nname = \"n1\"\nkind = \"ideal\"\n"}}, {"network"});
  const toml::table back = toml::parse(text);
  ASSERT_EQ(back["link"].as_array()->size(), 1U) << text;
  EXPECT_EQ(back["link"][0]["kind"].value<std::string>(), "ideal") << text;
}

TEST(LadderScenario, RelativeInputPathsAreRebasedOnTheOutputFolder) {
  toml::table doc = ladder_document("proj/s.toml", kText, {}, 0, 0, std::nullopt);
  rebase_input_paths(doc, {{"data/t.csv", "0123456789abcdef"}}, "proj", "proj/out/ladder");
  EXPECT_EQ(doc["link"][1]["file"].value<std::string>(), "../../data/t.csv");
  EXPECT_EQ(doc["link"][0]["name"].value<std::string>(), "n1");  // not a file: untouched
}

TEST(LadderBand, InsideOnlyWhenCompareSaysUnchangedAndItsIntervalIsInTheBand) {
  CompareRow row;
  row.verdict = "unchanged";
  row.relative = 0.01;
  row.relative_low = -0.02;
  row.relative_high = 0.04;
  EXPECT_EQ(band_verdict(row, 0.05), "inside");
  row.relative_high = 0.06;  // no significant change, but not shown to be within 5 % either
  EXPECT_EQ(band_verdict(row, 0.05), "inconclusive");
  row.relative_low.reset();
  row.relative_high.reset();
  EXPECT_EQ(band_verdict(row, 0.05), "inconclusive");
  row.verdict = "worse";
  EXPECT_EQ(band_verdict(row, 0.05), "worse");
}

}  // namespace
}  // namespace ncosim::sim
