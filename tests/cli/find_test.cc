// tests/cli/find_test.cc — `ncosim find` as a user drives it (exit codes, messages, find.csv),
// the monotonicity check behind it, and design.csv of `ncosim design` with a sweep.
#include "sim/cmd/find.h"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "test_util.h"

namespace {

namespace fs = std::filesystem;

const std::string kBinary = NCOSIM_BINARY;
const fs::path kFig5 = fs::path(NCOSIM_SOURCE_DIR) / "scenarios" / "dolz2014_fig5.toml";

using Outcome = ncosim::testing::CommandOutcome;

Outcome ncosim(const std::string& args) {
  return ncosim::testing::run_shell(fmt::format("'{}' {}", kBinary, args));
}

std::string slurp(const fs::path& p) { return ncosim::testing::read_text(p.string()); }

fs::path fresh_dir(const std::string& name) {
  const fs::path d = fs::temp_directory_path() / fmt::format("ncosim_find_{}_{}", name, ::getpid());
  fs::remove_all(d);
  return d;
}

TEST(FindCli, WritesTheThresholdAndFindCsv) {
  const fs::path out = fresh_dir("ok");
  const Outcome o =
      ncosim(fmt::format("find '{}' --key 'link[0].delivery' --target 'predicted_mse<=0.03' "
                         "--estimator 'S4 N1 b0' --lo 0.5 --hi 1 --tol 1e-4 --out '{}'",
                         kFig5.string(), out.string()));
  ASSERT_EQ(o.code, 0) << o.output;
  EXPECT_NE(o.output.find("S4 N1 b0"), std::string::npos) << o.output;
  const std::string csv = slurp(out / "find.csv");
  std::istringstream lines(csv);
  std::string head, row, extra;
  ASSERT_TRUE(std::getline(lines, head));
  EXPECT_EQ(head,
            "estimator,key,quantity,op,target,threshold,other_end,value_at_threshold,evaluations,"
            "monotone,status");
  ASSERT_TRUE(std::getline(lines, row));
  EXPECT_FALSE(std::getline(lines, extra)) << "one row: one estimator, the swept key is searched";
  EXPECT_EQ(row.rfind("S4 N1 b0,link[0].delivery,predicted_mse,<=,0.03,0.97", 0), 0u) << row;
  EXPECT_NE(row.find(",true,ok"), std::string::npos) << row;
  EXPECT_TRUE(fs::exists(out / "manifest.json"));
  fs::remove_all(out);
}

TEST(FindCli, BadInputIsExit2WithAMessage) {
  const std::string base =
      fmt::format("find '{}' --key 'link[0].delivery' --lo 0.5 --hi 1 ", kFig5.string());
  Outcome o = ncosim(base + "--target 'predicted_mse=0.03'");
  EXPECT_EQ(o.code, 2);
  EXPECT_NE(o.output.find("--target: expected QUANTITY<=VALUE"), std::string::npos) << o.output;
  o = ncosim(base + "--target 'predicted_mse<=x'");
  EXPECT_EQ(o.code, 2);
  EXPECT_NE(o.output.find("the value is not a number"), std::string::npos) << o.output;
  o = ncosim(base + "--target 'predicted_mse<=0.03' --estimator 'S4 N1 b9'");
  EXPECT_EQ(o.code, 2);
  EXPECT_NE(o.output.find("did you mean \"S4 N1 b0\""), std::string::npos) << o.output;
  o = ncosim(fmt::format(
      "find '{}' --key 'link[0].delivery' --lo 1 --hi 0.5 --target 'predicted_mse<=0.03'",
      kFig5.string()));
  EXPECT_EQ(o.code, 2);
  EXPECT_NE(o.output.find("expected lo < hi"), std::string::npos) << o.output;
  // A value the scenario rejects is reported at its key, as with --set.
  o = ncosim(fmt::format(
      "find '{}' --key 'link[0].delivery' --lo 0.5 --hi 1.5 --target 'predicted_mse<=0.03'",
      kFig5.string()));
  EXPECT_EQ(o.code, 2);
  EXPECT_NE(o.output.find("--key: 'link[0].delivery' = 1.125: expected a probability"),
            std::string::npos)
      << o.output;
}

// Issue 40 part 8: an entry of an array of numbers (link[0].pmf[0], the obvious key on the
// flagship) is searched, the array's other entries as the scenario has them; errors of --key
// name --key (they said `--set:`) with the value tried.
TEST(FindCli, AnArrayEntryIsSearchedAndKeyErrorsNameKey) {
  const std::string flagship =
      (fs::path(NCOSIM_SOURCE_DIR) / "scenarios" / "dolz2014_table2.toml").string();
  const std::string target =
      "--target 'predicted_mse<=0.1' --estimator 'S1, 1 gain' --scan 4 --tol 1e-3";
  const fs::path out = fresh_dir("entry");
  Outcome o =
      ncosim(fmt::format("find '{}' --key 'link[0].pmf[0]' --lo 0.3 --hi 0.65 {} --out '{}'",
                         flagship, target, out.string()));
  ASSERT_EQ(o.code, 0) << o.output;
  const std::string csv = slurp(out / "find.csv");
  EXPECT_NE(csv.find("\"S1, 1 gain\",link[0].pmf[0],predicted_mse,<=,0.1,0.39"), std::string::npos)
      << csv;
  EXPECT_NE(csv.find(",true,ok"), std::string::npos) << csv;
  fs::remove_all(out);
  // The threshold is the value that --set of the whole array gives the same design with.
  o =
      ncosim(fmt::format("find '{}' --key 'link[0].pmf[0]' --lo 0.3 --hi 0.65 {} "
                         "--set 'link[0].pmf=[0.3, 0.2]'",
                         flagship, target));
  ASSERT_EQ(o.code, 0) << o.output;
  EXPECT_EQ(o.output.find("0.394336"), std::string::npos) << "--set's array is the one searched";
  const std::string base = fmt::format("find '{}' {} ", flagship, target);
  struct Bad {
    std::string key, lo_hi, says;
  };
  for (const Bad& b : std::vector<Bad>{
           {"link[0].pmf[5]", "--lo 0.1 --hi 0.6",
            "--key: 'link[0].pmf[5]': 'link[0].pmf' has 2 entries (0-based: link[0].pmf[0] .. "
            "link[0].pmf[1])"},
           {"link[0].name[0]", "--lo 0.1 --hi 0.6",
            "--key: 'link[0].name[0]' names an entry of 'link[0].name', which is not an array of "
            "numbers"},
           {"link[0].pmf[x]", "--lo 0.1 --hi 0.6", "--key: expected a key path"},
           {"link[0].bogus", "--lo 0.1 --hi 0.6", "--key: 'link[0].bogus' = 0.1: unknown key"},
           {"link[7].delivery", "--lo 0.1 --hi 0.6",
            "--key: 'link[7].delivery' = 0.1: there is no [[link]] number 7"},
           {"link[0].pmf[0]", "--lo 0.1 --hi 0.9", "--key: 'link[0].pmf[0]' = 0.7"},
       }) {
    o = ncosim(base + fmt::format("--key '{}' {}", b.key, b.lo_hi));
    EXPECT_EQ(o.code, 2) << b.key << ": " << o.output;
    EXPECT_NE(o.output.find("ncosim: " + b.says), std::string::npos) << b.key << ": " << o.output;
    EXPECT_EQ(o.output.find("--set"), std::string::npos) << b.key << ": " << o.output;
  }
}

TEST(FindCli, NoThresholdInTheRangeIsAWarningAndAnEmptyThreshold) {
  const fs::path out = fresh_dir("nb");
  const Outcome o =
      ncosim(fmt::format("find '{}' --key 'link[0].delivery' --target 'predicted_mse<=0.03' "
                         "--estimator 'S4 N1 b0' --lo 0.5 --hi 0.9 --out '{}'",
                         kFig5.string(), out.string()));
  ASSERT_EQ(o.code, 0) << o.output;
  EXPECT_NE(o.output.find("never meets the target"), std::string::npos) << o.output;
  EXPECT_NE(slurp(out / "find.csv").find(",0.03,,,,9,true,not_bracketed"), std::string::npos)
      << slurp(out / "find.csv");
  fs::remove_all(out);
}

TEST(FindMonotone, DetectsAReversal) {
  using P = std::map<double, std::optional<double>>;
  EXPECT_TRUE(ncosim::sim::is_monotone(P{{0.0, 3.0}, {0.5, 2.0}, {1.0, 1.0}}));
  EXPECT_TRUE(ncosim::sim::is_monotone(P{{0.0, 1.0}, {0.5, 1.0}, {1.0, 2.0}}));
  EXPECT_TRUE(ncosim::sim::is_monotone(P{{0.0, std::nullopt}, {0.5, 2.0}, {1.0, 1.0}}));
  EXPECT_FALSE(ncosim::sim::is_monotone(P{{0.0, 3.0}, {0.5, 1.0}, {1.0, 2.0}}));
  EXPECT_FALSE(
      ncosim::sim::is_monotone(P{{0.0, 1.0}, {0.2, 2.0}, {0.5, std::nullopt}, {1.0, 1.5}}));
}

TEST(DesignCsv, OneRowPerCaseAndEstimator) {
  const fs::path out = fresh_dir("csv");
  const Outcome o =
      ncosim(fmt::format("design '{}' --set 'sweep[0].values=[0.9, 0.95, 1.0]' --out '{}'",
                         kFig5.string(), out.string()));
  ASSERT_EQ(o.code, 0) << o.output;
  std::istringstream lines(slurp(out / "design.csv"));
  std::string line;
  ASSERT_TRUE(std::getline(lines, line));
  EXPECT_EQ(line,
            "link[0].delivery,estimator,kind,method,predicted_mse,predicted_mse_ext,stored_gains,"
            "flops_per_period,p0,design_seconds,status,predicted_mse_paper_eq28_erroneous");
  int rows = 0;
  while (std::getline(lines, line)) {
    ++rows;
    EXPECT_NE(line.find(",jump,iterative,"), std::string::npos) << line;
    EXPECT_NE(line.find(",ok,"), std::string::npos)
        << line;  // status, then the printed eq. (28) value
    EXPECT_NE(line.back(), ',') << line;
  }
  EXPECT_EQ(rows, 3 * 4);
  fs::remove_all(out);
}

}  // namespace

namespace {

TEST(DelayLinkDelivery, ScalesTheShapeAndRejectsMixedForms) {
  const fs::path out = fresh_dir("delivery");
  // delivery 0.9 spread over delays 0 and 1 as 1:3: P[delay 0] = 0.225, so the b = 0 observers
  // (max_delay 0) see p0 = 0.775.
  Outcome o = ncosim(fmt::format(
      "design '{}' --set 'sweep[0].values=[0.9]' --set 'link[0].shape=[1.0, 3.0]' --out '{}'",
      kFig5.string(), out.string()));
  ASSERT_EQ(o.code, 0) << o.output;
  EXPECT_NE(slurp(out / "design.csv").find("0.9,S4 N1 b0,jump,iterative,"), std::string::npos);
  EXPECT_NE(slurp(out / "design.csv").find(",0.775,"), std::string::npos)
      << slurp(out / "design.csv");
  o = ncosim(fmt::format("check '{}' --set 'link[0].pmf=[0.5]'", kFig5.string()));
  EXPECT_EQ(o.code, 2);
  EXPECT_NE(o.output.find("expected either pmf or delivery (with shape), got both"),
            std::string::npos)
      << o.output;
  o = ncosim(fmt::format("check '{}' --set 'link[0].shape=[0.0, 0.0]'", kFig5.string()));
  EXPECT_EQ(o.code, 2);
  EXPECT_NE(o.output.find("key 'link[0].shape': expected at least one positive weight"),
            std::string::npos)
      << o.output;
  o = ncosim(fmt::format("check '{}' --set 'sweep[0].values=[1.2]'", kFig5.string()));
  EXPECT_EQ(o.code, 2);
  EXPECT_NE(o.output.find("link[0].delivery"), std::string::npos) << o.output;
  fs::remove_all(out);
}

}  // namespace
