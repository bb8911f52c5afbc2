// tests/cli/compare_cli_test.cc — `ncosim compare` as a CI job drives it (exit 0 / 1 / 2, the
// files, messages naming the file or option), `run --fail-on-status` and the exit of
// `codesign` with a status that is not ok.
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <string>

#include "test_util.h"

namespace {

namespace fs = std::filesystem;

const std::string kBinary = NCOSIM_BINARY;
const fs::path kTable2 = fs::path(NCOSIM_SOURCE_DIR) / "scenarios" / "dolz2014_table2.toml";

using Outcome = ncosim::testing::CommandOutcome;

Outcome ncosim(const std::string& args) { return ncosim::testing::run_shell(fmt::format("'{}' {}", kBinary, args)); }

class CompareCli : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / fmt::format("ncosim_compare_cli_{}", ::getpid());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  // A short flagship campaign into dir_/name with extra options.
  void run(const std::string& name, const std::string& extra = "") {
    const Outcome o = ncosim(fmt::format("run '{}' --out '{}' --runs 6 --periods 3000 --quiet {}", kTable2.string(),
                                         (dir_ / name).string(), extra));
    ASSERT_EQ(o.code, 0) << o.output;
  }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  fs::path dir_;
};

TEST_F(CompareCli, UnchangedIsExit0AndARegressionExit1WithTheFiles) {
  run("base");
  run("same");
  Outcome o = ncosim(fmt::format("compare '{}' '{}' --out '{}'", path("base"), path("same"), path("cmp")));
  EXPECT_EQ(o.code, 0) << o.output;
  EXPECT_NE(o.output.find("0 worse, 0 better, 6 unchanged, 1 not comparable: exit 0"), std::string::npos) << o.output;
  EXPECT_TRUE(fs::exists(dir_ / "cmp" / "compare.csv"));
  EXPECT_TRUE(fs::exists(dir_ / "cmp" / "compare.md"));
  // S4 replaced by S1's grouping (+170 % MSE): another scenario hash, so exit 2 without the flag.
  run("worse", "--set 'estimator[4].grouping=\"S1\"'");
  o = ncosim(fmt::format("compare '{}' '{}'", path("base"), path("worse")));
  EXPECT_EQ(o.code, 2) << o.output;
  EXPECT_NE(o.output.find(path("worse") + "/manifest.json: a different scenario or different overrides"),
            std::string::npos)
      << o.output;
  o = ncosim(fmt::format("compare '{}' '{}' --allow-scenario-change --metric mse_ext", path("base"), path("worse")));
  EXPECT_EQ(o.code, 1) << o.output;
  EXPECT_NE(o.output.find("| S4, 60 gains | **worse** | paired | 6 |"), std::string::npos) << o.output;
  // A bigger tolerance than the change: not a regression.
  o = ncosim(fmt::format("compare '{}' '{}' --allow-scenario-change --tolerance 0.99", path("base"), path("worse")));
  EXPECT_EQ(o.code, 0) << o.output;
}

TEST_F(CompareCli, BadInputIsExit2NamingTheFileOrOption) {
  run("base");
  Outcome o = ncosim(fmt::format("compare '{}' '{}'", path("base"), path("missing")));
  EXPECT_EQ(o.code, 2) << o.output;
  EXPECT_NE(o.output.find(path("missing") + ": not a directory"), std::string::npos) << o.output;
  o = ncosim(fmt::format("compare '{}' '{}' --metric msee", path("base"), path("base")));
  EXPECT_EQ(o.code, 2) << o.output;
  EXPECT_NE(o.output.find("--metric: expected a per-run column"), std::string::npos) << o.output;
  o = ncosim(fmt::format("compare '{}' '{}' --alpha 1.5", path("base"), path("base")));
  EXPECT_EQ(o.code, 2) << o.output;
  EXPECT_NE(o.output.find("--alpha: expected a level in (0, 1)"), std::string::npos) << o.output;
  o = ncosim(fmt::format("compare '{}' '{}' --correction bonferroni", path("base"), path("base")));
  EXPECT_EQ(o.code, 2) << o.output;
  EXPECT_NE(o.output.find("--correction"), std::string::npos) << o.output;
  o = ncosim(fmt::format("compare '{}'", path("base")));
  EXPECT_EQ(o.code, 2) << o.output;
}

TEST_F(CompareCli, FailOnStatusListsTheRowsAndExits3) {
  // The flagship's open-loop row always diverges (A3 is unstable).
  const Outcome o = ncosim(fmt::format("run '{}' --out '{}' --runs 2 --periods 1000 --quiet --fail-on-status",
                                       kTable2.string(), path("fos")));
  EXPECT_EQ(o.code, 3) << o.output;
  EXPECT_NE(o.output.find("--fail-on-status: 1 row(s) not ok"), std::string::npos) << o.output;
  EXPECT_NE(o.output.find("\"open loop\": diverged"), std::string::npos) << o.output;
  EXPECT_TRUE(fs::exists(dir_ / "fos" / "summary.csv"));  // the results are written first
  // Without the open-loop row every status is ok: exit 0.
  const Outcome ok = ncosim(fmt::format("run '{}' --out '{}' --runs 2 --periods 1000 --quiet --fail-on-status "
                                        "--set 'estimator=[{{kind=\"kalman_extended\", max_delay=1}}]'",
                                        kTable2.string(), path("fos2")));
  EXPECT_EQ(ok.code, 0) << ok.output;
}

TEST_F(CompareCli, CodesignWithAStatusNotOkExits3AndPrintsNoApplyLine) {
  // Example 5.1, deterministic C1 at mu = 1.05: the bound at delta0 is already 1.18 z~0 above
  // the target (results/sod_example51/README.md): start_infeasible.
  const std::string file = std::string(NCOSIM_SOURCE_DIR) + "/scenarios/sod_example51.toml";
  const Outcome o = ncosim(fmt::format("codesign '{}' --out '{}' --estimator C1 --mu 1.05 --quiet", file, path("cd")));
  EXPECT_EQ(o.code, 3) << o.output;
  EXPECT_EQ(o.output.find("apply:"), std::string::npos) << o.output;
  EXPECT_NE(o.output.find("status start_infeasible"), std::string::npos) << o.output;
  EXPECT_NE(ncosim::testing::read_text(path("cd") + "/codesign.json").find("\"apply\": null"), std::string::npos);
}

}  // namespace
