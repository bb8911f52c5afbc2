// tests/cli/list_keys_cli_test.cc — `ncosim list --keys [KIND] [--format md]` prints the declared
// keys of a kind (config/keys.h): type, unit, default, range or values and help; an unknown kind
// exits 2 with a did-you-mean. `ncosim list` names the fit families.
#include <gtest/gtest.h>

#include <string>

#include "test_util.h"

namespace {

using Outcome = ncosim::testing::CommandOutcome;
using ncosim::testing::run_ncosim;

TEST(ListKeys, PrintsOneKindsDeclarations) {
  const Outcome o = run_ncosim({"list", "--keys", "link.bernoulli"});
  ASSERT_EQ(o.code, 0) << o.output;
  EXPECT_NE(o.output.find("link.bernoulli: lost with probability loss"), std::string::npos)
      << o.output;
  EXPECT_NE(o.output.find("  loss             number    default 0.0  allowed [0, 1]\n"),
            std::string::npos)
      << o.output;
  EXPECT_NE(o.output.find("  delay            integer  [periods]  default 0  allowed 0..1000000\n"),
            std::string::npos)
      << o.output;
}

TEST(ListKeys, MarkdownIsTheReadmeTable) {
  const Outcome o = run_ncosim({"list", "--keys", "link.negative_binomial", "--format", "md"});
  ASSERT_EQ(o.code, 0) << o.output;
  EXPECT_EQ(o.output.rfind("| key | type | unit | default | allowed | meaning |\n", 0), 0u)
      << o.output;
  EXPECT_NE(o.output.find("| `successes` | integer |  | required | 1..10000 |"), std::string::npos)
      << o.output;
  EXPECT_NE(o.output.find("| `p` | number |  | required | (0, 1] |"), std::string::npos)
      << o.output;
}

TEST(ListKeys, EveryKindWithoutAName) {
  const Outcome o = run_ncosim({"list", "--keys"});
  ASSERT_EQ(o.code, 0) << o.output;
  for (const char* kind : {"plant.lti", "plant.jump_linear", "link.markov", "link.trace",
                           "input.pi", "send_policy.send_on_delta"}) {
    EXPECT_NE(o.output.find(std::string(kind) + ": "), std::string::npos) << kind;
  }
  EXPECT_NE(o.output.find("reference.period"), std::string::npos) << o.output;  // a table's field
}

TEST(ListKeys, AnUnknownKindExits2WithADidYouMean) {
  const Outcome o = run_ncosim({"list", "--keys", "link.bernouli"});
  EXPECT_EQ(o.code, 2) << o.output;
  EXPECT_NE(o.output.find("got 'link.bernouli' (did you mean 'link.bernoulli'?)"),
            std::string::npos)
      << o.output;
}

TEST(ListKeys, ListNamesTheFitFamilies) {
  const Outcome o = run_ncosim({"list"});
  ASSERT_EQ(o.code, 0) << o.output;
  EXPECT_NE(o.output.find("fit families (ncosim fit --family):\n  bernoulli "), std::string::npos)
      << o.output;
  EXPECT_NE(o.output.find("  markov8 "), std::string::npos) << o.output;
}

}  // namespace
