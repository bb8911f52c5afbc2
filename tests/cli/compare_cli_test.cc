// tests/cli/compare_cli_test.cc — `ncosim compare` as a CI job drives it (exit 0 / 1 / 2 / 4, the
// files, messages naming the file or option, nothing written on bad input), `run
// --fail-on-status` and the exit of `codesign` with a status that is not ok.
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "test_util.h"

namespace {

namespace fs = std::filesystem;

const std::string kBinary = NCOSIM_BINARY;
const fs::path kTable2 = fs::path(NCOSIM_SOURCE_DIR) / "scenarios" / "dolz2014_table2.toml";

using Outcome = ncosim::testing::CommandOutcome;

Outcome ncosim(const std::string& args) {
  return ncosim::testing::run_shell(fmt::format("'{}' {}", kBinary, args));
}

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
  // A short flagship campaign into dir_/name with extra options (8 runs: with 6 rows under
  // Holm's correction, 6 pairs cannot show anything, 2^-6 > 0.05 / 6).
  void run(const std::string& name, const std::string& extra = "") {
    const Outcome o = ncosim(fmt::format("run '{}' --out '{}' --runs 8 --periods 3000 --quiet {}",
                                         kTable2.string(), (dir_ / name).string(), extra));
    ASSERT_EQ(o.code, 0) << o.output;
  }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  // A hand-made output folder dir_/name: manifest.json and a runs.csv of estimators "a" and "b",
  // `runs` runs each, mse = level (1 + (r mod 7) / 10) ("b": times 1.1), then `extra` columns
  // rmse_x1.. of 17 characters each (a wide file: a model with many states). Returns runs.csv.
  std::string hand_made(const std::string& name, int runs, double level, int extra = 1) const {
    fs::create_directories(dir_ / name);
    std::ofstream(dir_ / name / "manifest.json")
        << R"({"scenario": "x.toml", "scenario_hash": "h", "seed": 1})";
    std::ofstream out(dir_ / name / "runs.csv");
    std::string line =
        "run,estimator,mse,mse_ext,periods,samples_used,samples_taken,diverged,status,flops_mean,"
        "late_samples,duplicate_samples,mde_percent";
    for (int i = 1; i <= extra; ++i) line += fmt::format(",rmse_x{}", i);
    out << line << "\n";
    std::string tail;
    for (int i = 0; i < extra; ++i) tail += ",0.123456789012345";
    for (int r = 0; r < runs; ++r) {
      for (const auto& [est, f] : {std::pair<const char*, double>{"a", 1.0}, {"b", 1.1}}) {
        out << fmt::format("{},{},{:.17g},,100,1,1,0,ok,,,,{}\n", r, est,
                           f * level * (1.0 + (r % 7) / 10.0), tail);
      }
    }
    return (dir_ / name / "runs.csv").string();
  }
  fs::path dir_;
};

// Runs ncosim with `args` (stdout and stderr to /dev/null): its exit status and peak resident
// set size in kB (wait4's ru_maxrss of that child alone).
std::pair<int, long> exit_and_peak_rss_kb(const std::vector<std::string>& args) {
  std::vector<char*> argv{const_cast<char*>(kBinary.c_str())};
  for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  const pid_t pid = ::fork();
  if (pid == 0) {
    std::freopen("/dev/null", "w", stdout);
    std::freopen("/dev/null", "w", stderr);
    ::execv(kBinary.c_str(), argv.data());
    ::_exit(127);
  }
  int status = 0;
  struct rusage ru {};
  if (pid < 0 || ::wait4(pid, &status, 0, &ru) != pid) return {-1, 0};
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, ru.ru_maxrss};
}

TEST_F(CompareCli, UnchangedIsExit0AndARegressionExit1WithTheFiles) {
  run("base");
  run("same");
  Outcome o =
      ncosim(fmt::format("compare '{}' '{}' --out '{}'", path("base"), path("same"), path("cmp")));
  EXPECT_EQ(o.code, 0) << o.output;
  EXPECT_NE(
      o.output.find("0 worse, 0 better, 6 unchanged, 0 inconclusive, 1 not comparable: exit 0"),
      std::string::npos)
      << o.output;
  EXPECT_TRUE(fs::exists(dir_ / "cmp" / "compare.csv"));
  EXPECT_TRUE(fs::exists(dir_ / "cmp" / "compare.md"));
  // S4 replaced by S1's grouping (+170 % MSE): another scenario hash, so exit 2 without the flag.
  run("worse", "--set 'estimator[4].grouping=\"S1\"'");
  o = ncosim(fmt::format("compare '{}' '{}'", path("base"), path("worse")));
  EXPECT_EQ(o.code, 2) << o.output;
  EXPECT_NE(
      o.output.find(path("worse") + "/manifest.json: a different scenario or different overrides"),
      std::string::npos)
      << o.output;
  EXPECT_NE(o.output.find("\n  overrides: [] -> [\"estimator[4].grouping=\\\"S1\\\"\"]"),
            std::string::npos)
      << o.output;
  o = ncosim(fmt::format("compare '{}' '{}' --allow-scenario-change --metric mse_ext", path("base"),
                         path("worse")));
  EXPECT_EQ(o.code, 1) << o.output;
  EXPECT_NE(o.output.find("| S4, 60 gains | **worse** | paired | 8 | 0.04"), std::string::npos)
      << o.output;
  EXPECT_NE(o.output.find(" | ×2.5"), std::string::npos) << o.output;  // a factor, not +150 %
  // Issue 40's regression: the Kalman filter ignoring every late sample (it was "unchanged",
  // exit 0, with a change of +11514 % [-4061, +27090]).
  run("md0", "--set 'estimator[5].max_delay=0'");
  o = ncosim(fmt::format("compare '{}' '{}' --allow-scenario-change", path("base"), path("md0")));
  EXPECT_EQ(o.code, 1) << o.output;
  EXPECT_NE(o.output.find("| Kalman | **worse** | paired | 8 |"), std::string::npos) << o.output;
}

TEST_F(CompareCli, InconclusiveFailsTheGateWithExit4UnlessAllowed) {
  // 3 runs a side: no claim can be made; exit 4, the hint in the output; --allow-inconclusive
  // passes (exit 0) and says so; the files are written either way.
  hand_made("few_a", 3, 1.0);
  hand_made("few_b", 3, 1.0);
  Outcome o = ncosim(
      fmt::format("compare '{}' '{}' --out '{}'", path("few_a"), path("few_b"), path("cmp")));
  EXPECT_EQ(o.code, 4) << o.output;
  EXPECT_NE(
      o.output.find("0 worse, 0 better, 0 unchanged, 2 inconclusive, 0 not comparable: exit 4\n"
                    "- an inconclusive row fails the gate (exit 4)"),
      std::string::npos)
      << o.output;
  EXPECT_NE(ncosim::testing::read_text(path("cmp") + "/compare.csv")
                .find("b,mse,inconclusive,paired,3,3,3,"),
            std::string::npos);
  o = ncosim(fmt::format("compare '{}' '{}' --allow-inconclusive", path("few_a"), path("few_b")));
  EXPECT_EQ(o.code, 0) << o.output;
  EXPECT_NE(o.output.find("- inconclusive rows pass (--allow-inconclusive)"), std::string::npos)
      << o.output;
  // --tolerance 0 is the plain "did it change?" only with --allow-inconclusive.
  o = ncosim(fmt::format("compare '{}' '{}' --tolerance 0 --allow-inconclusive", path("few_a"),
                         path("few_b")));
  EXPECT_EQ(o.code, 0) << o.output;
}

TEST_F(CompareCli, AnotherSeedOrMoreRunsOfTheSameScenarioCompareWithoutTheOption) {
  // The same scenario text with --seed 99, or with --runs 8: compared without
  // --allow-scenario-change (both were exit 2, naming nothing), every differing field listed.
  run("base");
  run("seed", "--seed 99");
  Outcome o =
      ncosim(fmt::format("compare '{}' '{}' --out '{}'", path("base"), path("seed"), path("cmp")));
  EXPECT_EQ(o.code, 4) << o.output;
  EXPECT_NE(o.output.find("  - seed: 2014 -> 99\n"), std::string::npos) << o.output;
  EXPECT_NE(o.output.find("- test: unpaired, Wilcoxon's rank-sum test of the two sets of runs: the "
                          "seeds differ (2014 -> 99)"),
            std::string::npos)
      << o.output;
  // 8 runs of 3000 periods a side cannot show a row within 5 %: inconclusive, exit 4.
  EXPECT_NE(o.output.find("| Kalman | inconclusive | unpaired | 8 / 8 |"), std::string::npos)
      << o.output;
  EXPECT_NE(ncosim::testing::read_text(path("cmp") + "/compare.csv").find(",unpaired,8,8,0,"),
            std::string::npos);
  EXPECT_NE(o.output.find("different seeds: unpaired"), std::string::npos) << o.output;
  // The manifests: scenario_text_hash is the same (text and --set), scenario_hash is not (it
  // also covers --seed, as results/README.md says).
  const std::string mb = ncosim::testing::read_text(path("base") + "/manifest.json");
  const std::string ms = ncosim::testing::read_text(path("seed") + "/manifest.json");
  auto field = [](const std::string& m, const std::string& key) {
    const auto at = m.find("\"" + key + "\": \"");
    return at == std::string::npos ? std::string("missing") : m.substr(at + key.size() + 5, 16);
  };
  EXPECT_EQ(field(mb, "scenario_text_hash"), field(ms, "scenario_text_hash"));
  EXPECT_NE(field(mb, "scenario_text_hash"), "missing");
  EXPECT_NE(field(mb, "scenario_hash"), field(ms, "scenario_hash"));
  // A manifest without scenario_text_hash (an older ncosim's): the text hash comes from the run
  // store's scenario text and --set, so the seeds still compare.
  const auto line = mb.find("  \"scenario_text_hash\"");
  ASSERT_NE(line, std::string::npos);
  std::ofstream(path("base") + "/manifest.json")
      << mb.substr(0, line) + mb.substr(mb.find('\n', line) + 1);
  o = ncosim(fmt::format("compare '{}' '{}'", path("base"), path("seed")));
  EXPECT_EQ(o.code, 4) << o.output;
  EXPECT_NE(o.output.find("  - scenario_text_hash: (absent) -> "), std::string::npos) << o.output;
  fs::remove(path("base") + "/runs.sqlite");  // and without a store: by scenario_hash, refused
  o = ncosim(fmt::format("compare '{}' '{}'", path("base"), path("seed")));
  EXPECT_EQ(o.code, 2) << o.output;
  EXPECT_NE(o.output.find(
                "a manifest.json without scenario_text_hash (an older ncosim) and no run store"),
            std::string::npos)
      << o.output;
  std::ofstream(path("base") + "/manifest.json") << mb;

  // --runs 10 (same seed): runs 0..7 are the same realisations, paired on them.
  o = ncosim(fmt::format("run '{}' --out '{}' --runs 10 --periods 3000 --quiet", kTable2.string(),
                         path("more")));
  ASSERT_EQ(o.code, 0) << o.output;
  o = ncosim(fmt::format("compare '{}' '{}'", path("base"), path("more")));
  EXPECT_EQ(o.code, 0) << o.output;
  EXPECT_NE(o.output.find("  - runs: 8 -> 10\n"), std::string::npos) << o.output;
  EXPECT_NE(o.output.find("- test: paired on the runs both folders have"), std::string::npos)
      << o.output;
  EXPECT_NE(o.output.find("| Kalman | unchanged | paired | 8 |"), std::string::npos) << o.output;
  EXPECT_NE(o.output.find("paired on the 8 runs both have"), std::string::npos) << o.output;
}

TEST_F(CompareCli, AnotherScenarioTextIsRefusedWithItsFirstDifferingLine) {
  // A copy of the flagship with one line changed: exit 2, the line and the fields named.
  std::string text = ncosim::testing::read_text(kTable2.string());
  const auto title = text.find("title = ");
  ASSERT_NE(title, std::string::npos);
  const auto eol = text.find('\n', title);
  const std::string old_line = text.substr(title, eol - title);
  text.replace(title, eol - title, "title = \"edited\"");
  const int line = 1 + static_cast<int>(std::count(
                           text.begin(), text.begin() + static_cast<std::ptrdiff_t>(title), '\n'));
  const fs::path copy = dir_ / "edited.toml";
  std::ofstream(copy) << text;
  run("base");
  const Outcome made = ncosim(fmt::format("run '{}' --out '{}' --runs 8 --periods 3000 --quiet",
                                          copy.string(), path("edited")));
  fs::remove(copy);
  ASSERT_EQ(made.code, 0) << made.output;
  const Outcome o = ncosim(fmt::format("compare '{}' '{}'", path("base"), path("edited")));
  EXPECT_EQ(o.code, 2) << o.output;
  EXPECT_NE(
      o.output.find(path("edited") + "/manifest.json: a different scenario or different overrides"),
      std::string::npos)
      << o.output;
  EXPECT_NE(o.output.find(fmt::format("\n  scenario text: line {}: `{}` -> `title = \"edited\"`",
                                      line, old_line)),
            std::string::npos)
      << o.output;
  EXPECT_NE(o.output.find("\n  scenario_text_hash: "), std::string::npos) << o.output;
  EXPECT_NE(o.output.find("\n  title: "), std::string::npos) << o.output;
  EXPECT_NE(o.output.find("\n  scenario: "), std::string::npos) << o.output;
  EXPECT_EQ(o.output.find("\n  seed: "), std::string::npos) << o.output;  // the same in both
}

TEST_F(CompareCli, BadInputIsExit2NamingTheFileOrOption) {
  run("base");
  Outcome o = ncosim(fmt::format("compare '{}' '{}'", path("base"), path("missing")));
  EXPECT_EQ(o.code, 2) << o.output;
  EXPECT_NE(o.output.find(path("missing") + ": not a directory"), std::string::npos) << o.output;
  o = ncosim(fmt::format("compare '{}' '{}' --metric msee", path("base"), path("base")));
  EXPECT_EQ(o.code, 2) << o.output;
  EXPECT_NE(o.output.find("--metric: expected a per-run column"), std::string::npos) << o.output;
  // Every option out of range or malformed: exit 2, the option named, no --out folder made.
  const std::vector<std::pair<std::string, std::string>> bad{
      {"--alpha 1.5", "--alpha: expected a level in (0, 0.5)"},
      {"--alpha 0.5", "--alpha: expected a level in (0, 0.5)"},
      {"--alpha x", "--alpha"},
      {"--correction bonferroni", "--correction"},
      {"--tolerance 0", "--tolerance: 0 leaves no row unchanged"},
      {"--tolerance 1", "--tolerance: expected a relative tolerance in [0, 1)"},
      {"--tolerance -0.1", "--tolerance: expected a relative tolerance in [0, 1)"},
      {"--tolerance nan", "--tolerance"},
      {"--tolerance five", "--tolerance"},
      {"--allow-inconclusive=maybe", "--allow-inconclusive"},
  };
  for (const auto& [args, message] : bad) {
    o = ncosim(fmt::format("compare '{}' '{}' {} --out '{}'", path("base"), path("base"), args,
                           path("never")));
    EXPECT_EQ(o.code, 2) << args << ": " << o.output;
    EXPECT_NE(o.output.find(message), std::string::npos) << args << ": " << o.output;
    EXPECT_FALSE(fs::exists(dir_ / "never")) << args;
  }
  // Bad input found reading the folders leaves no --out folder either (it used to be created
  // first, empty).
  o = ncosim(
      fmt::format("compare '{}' '{}' --out '{}'", path("base"), path("missing"), path("never")));
  EXPECT_EQ(o.code, 2) << o.output;
  EXPECT_FALSE(fs::exists(dir_ / "never"));
  o = ncosim(fmt::format("compare '{}'", path("base")));
  EXPECT_EQ(o.code, 2) << o.output;
}

TEST_F(CompareCli, HandMadeNonFiniteOrHugeValuesAreRefusedOrTested) {
  hand_made("base", 10, 1.0);
  // NEW = 1e160 x BASE is a regression (it was "unchanged": the variances overflowed), printed
  // as a factor (it was a 160-digit percentage).
  hand_made("huge", 10, 1e160);
  Outcome o = ncosim(fmt::format("compare '{}' '{}'", path("base"), path("huge")));
  EXPECT_EQ(o.code, 1) << o.output;
  EXPECT_NE(
      o.output.find("2 worse, 0 better, 0 unchanged, 0 inconclusive, 0 not comparable: exit 1"),
      std::string::npos)
      << o.output;
  EXPECT_NE(o.output.find(" | ×1e+160 [×1e+160, ×1e+160] | "), std::string::npos) << o.output;
  EXPECT_EQ(o.output.find("00000000"), std::string::npos) << o.output;
  // A non-finite, negative or out-of-range cell: exit 2 naming FILE:LINE (nan used to drop the
  // run; -1e308 gave "-inf [-nan, -nan]" and "unchanged").
  for (const std::string bad : {"nan", "inf", "-1e308", "1e999"}) {
    const std::string file = hand_made("bad", 10, 1.0);
    std::ofstream(file, std::ios::app) << "10,a," << bad << ",,100,1,1,0,ok,,,,,0.1\n";
    o = ncosim(fmt::format("compare '{}' '{}'", path("base"), path("bad")));
    EXPECT_EQ(o.code, 2) << bad << ": " << o.output;
    EXPECT_NE(o.output.find(file + ":22: mse: expected a finite number >= 0, got \"" + bad + "\""),
              std::string::npos)
        << o.output;
  }
}

TEST_F(CompareCli, MemoryFollowsTheRunsNotTheFileSize) {
  // A 66 MB runs.csv (400 state columns, 4 500 runs of 2 estimators): compare keeps the run
  // index and the metric of each run (~30 bytes), not the file (it used to hold the file and
  // every field as a string, ~6 times its size). Bound: 40 MB of peak RSS, less than the file.
  const std::string file = hand_made("wide", 4500, 1.0, 400);
  ASSERT_GT(fs::file_size(file), 60u * 1000 * 1000);
  const auto [code, kb] = exit_and_peak_rss_kb({"compare", path("wide"), path("wide")});
  EXPECT_EQ(code, 0);
  EXPECT_LT(kb, 40 * 1024) << "peak RSS " << kb << " kB";
}

TEST_F(CompareCli, FailOnStatusListsTheRowsAndExits3) {
  // The flagship's open-loop row always diverges (A3 is unstable); the shipped scenario expects
  // it (expected_status = "diverged", tests/cli/table_cli_test.cc), so it is declared ok here.
  const Outcome o =
      ncosim(fmt::format("run '{}' --out '{}' --runs 2 --periods 1000 --quiet --fail-on-status "
                         "--set 'estimator[6].expected_status=\"ok\"'",
                         kTable2.string(), path("fos")));
  EXPECT_EQ(o.code, 3) << o.output;
  EXPECT_NE(o.output.find("--fail-on-status: 1 row(s) with an unexpected status"),
            std::string::npos)
      << o.output;
  EXPECT_NE(o.output.find("\"open loop\": diverged"), std::string::npos) << o.output;
  EXPECT_TRUE(fs::exists(dir_ / "fos" / "summary.csv"));  // the results are written first
  // Without the open-loop row every status is ok: exit 0.
  const Outcome ok =
      ncosim(fmt::format("run '{}' --out '{}' --runs 2 --periods 1000 --quiet --fail-on-status "
                         "--set 'estimator=[{{kind=\"kalman_extended\", max_delay=1}}]'",
                         kTable2.string(), path("fos2")));
  EXPECT_EQ(ok.code, 0) << ok.output;
}

TEST_F(CompareCli, CodesignWithAStatusNotOkExits3AndPrintsNoApplyLine) {
  // Example 5.1, deterministic C1 at mu = 1.05: the bound at delta0 is already 1.18 z~0 above
  // the target (results/sod_example51/README.md): start_infeasible.
  const std::string file = std::string(NCOSIM_SOURCE_DIR) + "/scenarios/sod_example51.toml";
  const Outcome o = ncosim(
      fmt::format("codesign '{}' --out '{}' --estimator C1 --mu 1.05 --quiet", file, path("cd")));
  EXPECT_EQ(o.code, 3) << o.output;
  EXPECT_EQ(o.output.find("apply:"), std::string::npos) << o.output;
  EXPECT_NE(o.output.find("status start_infeasible"), std::string::npos) << o.output;
  EXPECT_NE(ncosim::testing::read_text(path("cd") + "/codesign.json").find("\"apply\": null"),
            std::string::npos);
}

}  // namespace
