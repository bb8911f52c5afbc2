// tests/cli/store_integrity_test.cc — the run store inside the result set's guarantees (issue 29):
// the store is swapped in with the exports (kills at every step of run, merge and export leave a
// store and exports that agree), `export A --out B` takes A's store, derived files do not outlive
// their campaign, input files are part of a campaign's identity, damaged rows and campaign fields
// are refused naming what is damaged, reading a store never writes it, and the fallback swap
// never loses the previous set.
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <sqlite3.h>
#include <sys/stat.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <random>
#include <regex>
#include <string>
#include <vector>

#include "cli/small_trace_scenario.h"
#include "cli/temp_dir_test.h"
#include "sim/store/store.h"
#include "test_util.h"

namespace {

namespace fs = std::filesystem;
using ncosim::testing::read_text;
using ncosim::testing::run_shell;

const std::string kBinary = NCOSIM_BINARY;
const fs::path kBase = fs::path(NCOSIM_SOURCE_DIR) / "tests" / "cli" / "data" / "base.toml";

std::string quote(const std::string& s) { return "'" + s + "'"; }

ncosim::testing::CommandOutcome ncosim(const std::string& args, const std::string& env = "") {
  return run_shell(env + quote(kBinary) + " " + args);
}

// Each test in a fresh temporary folder; at("x") is the path of x in it.
class StoreIntegrity : public ncosim::testing::TempDirTest {
 protected:
  StoreIntegrity() : TempDirTest("ncosim_integrity_") {}
  std::string at(const std::string& rel) const { return (dir_ / rel).string(); }
};

// The exports `ncosim export` re-derives from the store (the run here is --no-timing; design.json
// without its design_seconds lines).
const std::vector<std::string> kExports{"summary.csv",       "summary.md",    "runs.csv",
                                        "transmissions.csv", "confusion.csv", "design.json",
                                        "links.csv"};

std::string comparable(const fs::path& file) {
  if (!fs::exists(file)) return "<absent>";
  std::string text = read_text(file.string());
  if (file.filename() == "design.json")
    text = std::regex_replace(text, std::regex(".*design_seconds.*\n"), "");
  return text;
}

// `ncosim export DIR --out CHECK` reproduces DIR's exports byte for byte: the folder's store and
// exports agree.
void expect_store_and_exports_agree(const std::string& dir, const std::string& check,
                                    const std::string& what) {
  fs::remove_all(check);
  const auto r = ncosim(fmt::format("export {} --out {}", quote(dir), quote(check)));
  ASSERT_EQ(r.code, 0) << what << ": " << r.output;
  for (const auto& f : kExports) {
    EXPECT_EQ(comparable(fs::path(dir) / f), comparable(fs::path(check) / f))
        << what << ": " << f << " differs";
  }
}

const std::string kFlags = "--runs 6 --periods 300 --no-timing --quiet";

std::string run_cmd(const std::string& out, int seed, const std::string& extra = "") {
  return fmt::format("run {} --out {} {} --seed {}{}", quote(kBase.string()), quote(out), kFlags,
                     seed, extra);
}

// Finding 2 (and the "kills at every step"): a kill before each step of the set's write,
// for run, merge and export into a folder holding a previous set, leaves the previous or the new
// set, whose store and exports agree; a kill after the campaign's last run and before its exports
// leaves the previous set intact and the new store resumable beside it.
TEST_F(StoreIntegrity, KillsAtEveryStepOfRunMergeAndExportLeaveAStoreAndExportsThatAgree) {
  const std::string out = at("out");
  // References: the previous set (seed 1) and each command's new set (seed 2).
  ASSERT_EQ(ncosim(run_cmd(at("ref1"), 1)).code, 0);
  ASSERT_EQ(ncosim(run_cmd(at("ref2"), 2)).code, 0);
  ASSERT_EQ(ncosim(run_cmd(at("s1"), 2, " --shard 1/2")).code, 0);
  ASSERT_EQ(ncosim(run_cmd(at("s2"), 2, " --shard 2/2")).code, 0);
  const std::string runs1 = read_text(at("ref1/runs.csv")), runs2 = read_text(at("ref2/runs.csv"));
  const std::vector<std::pair<std::string, std::string>> commands{
      {"run", run_cmd(out, 2, " --replace")},  // replaces the seed-1 campaign deliberately
      {"merge",
       fmt::format("merge {} {} {} --replace", quote(out), quote(at("s1")), quote(at("s2")))},
      {"export", fmt::format("export {} --out {} --replace", quote(at("ref2")), quote(out))},
  };
  for (const auto& [name, cmd] : commands) {
    int kills = 0;
    for (int k = 1; k < 200; ++k) {
      fs::remove_all(out);  // a killed run's unfinished store beside it is replaced deliberately
      ASSERT_EQ(ncosim(run_cmd(out, 1, " --replace")).code, 0);
      const auto r = ncosim(cmd, fmt::format("NCOSIM_TEST_KILL_AT={} ", k));
      if (r.code == 0) break;
      ++kills;
      const std::string what = fmt::format("{} killed before step {}", name, k);
      const std::string runs = read_text(out + "/runs.csv");
      EXPECT_TRUE(runs == runs1 || runs == runs2) << what << ": runs.csv is neither set's";
      expect_store_and_exports_agree(out, at("check"), what);
    }
    EXPECT_GE(kills, 10) << name << ": the write sequence has fewer steps than expected";
  }
  // Killed after the last run, before the exports: the previous set stays whole and consistent,
  // and --resume finishes the new campaign from the store beside the folder.
  fs::remove_all(out);
  ASSERT_EQ(ncosim(run_cmd(out, 1)).code, 0);
  auto r = ncosim(run_cmd(out, 2, " --replace"), "NCOSIM_TEST_RAISE_AFTER_RUNS=9 ");
  ASSERT_NE(r.code, 0) << r.output;
  EXPECT_EQ(read_text(out + "/runs.csv"), runs1);
  expect_store_and_exports_agree(out, at("check"), "killed after the last run");
  ASSERT_TRUE(fs::exists(ncosim::sim::partial_store_path(out)));
  r = ncosim(run_cmd(out, 2, " --resume"));
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("6 runs x 300 periods (6 stored before, 0 simulated now)"),
            std::string::npos)
      << r.output;
  EXPECT_EQ(read_text(out + "/runs.csv"), runs2);
  EXPECT_FALSE(fs::exists(ncosim::sim::partial_store_path(out)));
  expect_store_and_exports_agree(out, at("check"), "resumed");
  // A new campaign without --resume does not replace an unfinished one (issue 28, part 3): it is
  // refused naming --replace, which replaces it and says so.
  r = ncosim(run_cmd(out, 3, " --replace"), "NCOSIM_TEST_RAISE_AFTER_RUNS=9 ");
  ASSERT_TRUE(fs::exists(ncosim::sim::partial_store_path(out))) << r.output;
  r = ncosim(run_cmd(out, 4));
  ASSERT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("holds 6 finished run(s) of a different, unfinished campaign"),
            std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find("`--replace` starts afresh"), std::string::npos) << r.output;
  r = ncosim(run_cmd(out, 4, " --replace"));
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("--replace: replacing 6 finished run(s) of a different campaign"),
            std::string::npos)
      << r.output;
}

// Finding 3: `export A --out B --replace` gives B A's exports *and* A's store; B's own store is
// gone (without --replace it is refused: ExportAndMergeReplaceAFolderOnlyWithReplace).
TEST_F(StoreIntegrity, ExportToAnotherFolderTakesTheStoreWithIt) {
  ASSERT_EQ(ncosim(run_cmd(at("a"), 1)).code, 0);
  ASSERT_EQ(ncosim(run_cmd(at("b"), 2)).code, 0);
  auto r = ncosim(fmt::format("export {} --out {} --replace", quote(at("a")), quote(at("b"))));
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_EQ(read_text(at("b/runs.csv")), read_text(at("a/runs.csv")));
  // Exporting B again must not flip its results back.
  r = ncosim(fmt::format("export {}", quote(at("b"))));
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_EQ(read_text(at("b/runs.csv")), read_text(at("a/runs.csv")));
  expect_store_and_exports_agree(at("b"), at("check"), "export --out");
}

// Issue 40 part 7: `export A --out B` and `merge B ...` follow the rule of `run --out B`: a folder
// holding runs of a different campaign (or runs the new store lacks, or an unfinished campaign
// beside it) is refused without --replace, exit 2, nothing written; a store whose every run
// comes back is replaced without a word.
TEST_F(StoreIntegrity, ExportAndMergeReplaceAFolderOnlyWithReplace) {
  ASSERT_EQ(ncosim(run_cmd(at("a"), 1)).code, 0);
  ASSERT_EQ(ncosim(run_cmd(at("b"), 2)).code, 0);
  ASSERT_EQ(ncosim(run_cmd(at("s1"), 2, " --shard 1/2")).code, 0);
  ASSERT_EQ(ncosim(run_cmd(at("s2"), 2, " --shard 2/2")).code, 0);
  const std::string runs_b = read_text(at("b/runs.csv"));
  auto unchanged = [&](const std::string& what) {
    EXPECT_EQ(read_text(at("b/runs.csv")), runs_b) << what;
    expect_store_and_exports_agree(at("b"), at("check"), what);
  };
  auto r = ncosim(fmt::format("export {} --out {}", quote(at("a")), quote(at("b"))));
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("export: '" + at("b") +
                          "' holds 6 finished run(s) of a different "
                          "campaign"),
            std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find("--seed ('2' vs '1')"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("`--replace` replaces them"), std::string::npos) << r.output;
  unchanged("export refused");
  // A shard of the same campaign lacks runs of the whole one: replacing would lose them.
  r = ncosim(fmt::format("export {} --out {}", quote(at("s1")), quote(at("b"))));
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("different campaign"), std::string::npos) << r.output;
  unchanged("export of a shard refused");
  // merge into a folder of a different campaign: refused; of the same campaign: every run comes
  // back, replaced.
  r = ncosim(fmt::format("merge {} {} {}", quote(at("a")), quote(at("s1")), quote(at("s2"))));
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("merge: '" + at("a") + "' holds 6 finished run(s) of a different"),
            std::string::npos)
      << r.output;
  EXPECT_FALSE(fs::exists(ncosim::sim::partial_store_path(at("a"))));
  r = ncosim(fmt::format("merge {} {} {}", quote(at("b")), quote(at("s1")), quote(at("s2"))));
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_EQ(r.output.find("--replace"), std::string::npos) << r.output;
  unchanged("merge of the same campaign");
  // An unfinished campaign beside the folder is the merge's too (it builds its store there).
  ASSERT_NE(ncosim(run_cmd(at("b"), 3, " --replace"), "NCOSIM_TEST_RAISE_AFTER_RUNS=9 ").code, 0);
  ASSERT_TRUE(fs::exists(ncosim::sim::partial_store_path(at("b"))));
  r = ncosim(fmt::format("merge {} {} {}", quote(at("b")), quote(at("s1")), quote(at("s2"))));
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("the store of an unfinished campaign"), std::string::npos) << r.output;
  EXPECT_TRUE(fs::exists(ncosim::sim::partial_store_path(at("b"))));
  r = ncosim(
      fmt::format("merge {} {} {} --replace", quote(at("b")), quote(at("s1")), quote(at("s2"))));
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("--replace: replacing 6 finished run(s) of a different campaign"),
            std::string::npos)
      << r.output;
  // With --replace, export replaces B's different campaign and says so.
  r = ncosim(fmt::format("export {} --out {} --replace", quote(at("a")), quote(at("b"))));
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("--replace: replacing 6 finished run(s) of a different campaign"),
            std::string::npos)
      << r.output;
  EXPECT_EQ(read_text(at("b/runs.csv")), read_text(at("a/runs.csv")));
}

// Finding 4: figures and reports of an earlier campaign do not survive a new one.
TEST_F(StoreIntegrity, ANewCampaignDropsWhatWasDerivedFromTheOldOne) {
  const std::string out = at("out");
  ASSERT_EQ(ncosim(run_cmd(out, 1)).code, 0);
  // What `plot` and `report` write (written by hand here: the test needs no gnuplot).
  for (const char* f : {"plot_mse.dat", "plot_mse.gp", "plot_mse.png", "trace.dat", "report.html"})
    write(out + "/" + f, "old");
  write(out + "/notes.txt", "mine");
  // Re-deriving the same campaign keeps them (they still describe it) ...
  ASSERT_EQ(ncosim(fmt::format("export {}", quote(out))).code, 0);
  EXPECT_TRUE(fs::exists(out + "/plot_mse.png"));
  EXPECT_TRUE(fs::exists(out + "/report.html"));
  // ... a new campaign does not; a file that ncosim does not derive stays.
  ASSERT_EQ(ncosim(run_cmd(out, 2, " --replace")).code, 0);
  for (const char* f :
       {"plot_mse.dat", "plot_mse.gp", "plot_mse.png", "trace.dat", "report.html"}) {
    EXPECT_FALSE(fs::exists(out + "/" + f)) << f;
  }
  EXPECT_EQ(read_text(out + "/notes.txt"), "mine");
}

// Finding 5: the content of every file a scenario reads is part of the campaign's identity:
// merge, --resume and export refuse when it differs, naming the file.
TEST_F(StoreIntegrity, InputFilesArePartOfTheCampaignsIdentity) {
  const std::string sc = at("sc.toml");
  write(sc, ncosim::testing::kSmallTraceScenario);
  write(at("trace.csv"), ncosim::testing::small_trace_csv(300, 3));
  const std::string flags = "--no-timing --quiet";
  ASSERT_EQ(
      ncosim(fmt::format("run {} --out {} --shard 1/2 {}", quote(sc), quote(at("s1")), flags)).code,
      0);
  write(at("trace.csv"), ncosim::testing::small_trace_csv(300, 2));
  ASSERT_EQ(
      ncosim(fmt::format("run {} --out {} --shard 2/2 {}", quote(sc), quote(at("s2")), flags)).code,
      0);
  auto r = ncosim(fmt::format("merge {} {} {}", quote(at("m")), quote(at("s1")), quote(at("s2"))));
  EXPECT_EQ(r.code, 2) << r.output;
  // Named relative to the scenario's folder (the same key whatever the working directory).
  EXPECT_NE(r.output.find("the content of the input file 'trace.csv'"), std::string::npos)
      << r.output;
  EXPECT_FALSE(fs::exists(at("m/summary.csv")));
  // --resume after the file changed: refused, naming it.
  r = ncosim(
      fmt::format("run {} --out {} --shard 1/2 --resume {}", quote(sc), quote(at("s1")), flags));
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("the content of the input file"), std::string::npos) << r.output;
  // export re-derives from the stored text, which reads the file again: it must be the same file.
  r = ncosim(fmt::format("export {} --out {}", quote(at("s1")), quote(at("e"))));
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("changed since the campaign ran"), std::string::npos) << r.output;
  write(at("trace.csv"), ncosim::testing::small_trace_csv(300, 3));
  r = ncosim(fmt::format("export {} --out {}", quote(at("s1")), quote(at("e"))));
  EXPECT_EQ(r.code, 0) << r.output;
  // The manifest names the file and its hash, and compare refuses two campaigns of the same
  // text over different contents of it, naming the file.
  EXPECT_NE(read_text(at("e/manifest.json")).find("\"inputs\""), std::string::npos);
  ASSERT_EQ(ncosim(fmt::format("run {} --out {} {}", quote(sc), quote(at("c1")), flags)).code, 0);
  write(at("trace.csv"), ncosim::testing::small_trace_csv(300, 2));
  ASSERT_EQ(ncosim(fmt::format("run {} --out {} {}", quote(sc), quote(at("c2")), flags)).code, 0);
  r = ncosim(fmt::format("compare {} {}", quote(at("c1")), quote(at("c2"))));
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("the content of the input file(s) 'trace.csv'"), std::string::npos)
      << r.output;
  r = ncosim(
      fmt::format("compare {} {} --allow-scenario-change", quote(at("c1")), quote(at("c2"))));
  EXPECT_NE(r.code, 2) << r.output;
  // The same file named from another working directory (a relative scenario path, as a user types
  // it; a shard run from elsewhere) is the same input: export, merge and --resume accept it.
  const std::string rel_run = fmt::format("cd {} && {} run sc.toml --out {} --no-timing --quiet",
                                          quote(dir_.string()), quote(kBinary), quote(at("r1")));
  ASSERT_EQ(run_shell(rel_run + " --shard 1/2").code, 0);
  ASSERT_EQ(
      ncosim(fmt::format("run {} --out {} --shard 2/2 {}", quote(sc), quote(at("r2")), flags)).code,
      0);
  r = ncosim(fmt::format("export {} --out {}", quote(at("r1")), quote(at("r1e"))));
  EXPECT_EQ(r.code, 0) << r.output;
  r = ncosim(fmt::format("merge {} {} {}", quote(at("rm")), quote(at("r1")), quote(at("r2"))));
  EXPECT_EQ(r.code, 0) << r.output;
  r = run_shell(fmt::format("cd / && {} run {} --out {} --shard 2/2 --resume {}", quote(kBinary),
                            quote(sc), quote(at("r2")), flags));
  EXPECT_EQ(r.code, 0) << r.output;
}

// Runs SQL on a store (the test's own connection).
void sql(const std::string& store, const std::string& statement) {
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(store.c_str(), &db), SQLITE_OK);
  char* err = nullptr;
  const int rc = sqlite3_exec(db, statement.c_str(), nullptr, nullptr, &err);
  EXPECT_EQ(rc, SQLITE_OK) << (err != nullptr ? err : "") << " in " << statement;
  sqlite3_free(err);
  sqlite3_close(db);
}

// Finding 6: a changed byte inside a stored run is refused by export, merge and resume, naming
// the run; so are run indices outside the campaign and unknown store formats.
TEST_F(StoreIntegrity, DamagedRowsAndIndicesAndFormatsAreRefused) {
  ASSERT_EQ(ncosim(run_cmd(at("a"), 1)).code, 0);
  auto fresh = [&](const std::string& name) {
    fs::remove_all(at(name));
    fs::create_directories(at(name));
    fs::copy_file(at("a/runs.sqlite"), at(name + "/runs.sqlite"));
    return at(name + "/runs.sqlite");
  };
  // 8 bytes of run 3's blob overwritten (what a bit rot or a stray write does; integrity_check
  // cannot see it).
  std::string store = fresh("b");
  sql(store,
      "UPDATE runs SET metrics = substr(metrics, 1, 40) || x'0102030405060708' || substr(metrics, "
      "49) "
      "WHERE run = 3");
  auto r = ncosim(fmt::format("export {}", quote(at("b"))));
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("run 3 of case 1 fails its checksum"), std::string::npos) << r.output;
  r = ncosim(fmt::format("merge {} {}", quote(at("m")), quote(at("b"))));
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("run 3 of case 1 fails its checksum"), std::string::npos) << r.output;
  r = ncosim(run_cmd(at("b"), 1, " --resume"));
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("run 3 of case 1 fails its checksum"), std::string::npos) << r.output;
  // The link counters, the timing and the stored files carry checksums too.
  store = fresh("c");
  sql(store,
      "UPDATE link_runs SET counters = substr(counters, 1, 8) || x'09' || substr(counters, 10) "
      "WHERE run = 1");
  r = ncosim(fmt::format("export {}", quote(at("c"))));
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("link counters of run 1 of case 1 fails its checksum"), std::string::npos)
      << r.output;
  store = fresh("c");
  sql(store, "UPDATE timing SET ns_per_period = 5 WHERE estimator = 0");
  r = ncosim(fmt::format("export {}", quote(at("c"))));
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("fails its checksum"), std::string::npos) << r.output;
  // A run index outside 0..runs-1 (the checksum recomputed: a deliberate edit, not rot).
  store = fresh("d");
  sql(store,
      "UPDATE runs SET run = 600 WHERE run = 5; UPDATE link_runs SET run = 600 WHERE run = 5");
  r = ncosim(fmt::format("export {}", quote(at("d"))));
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("run index 600, outside the campaign"), std::string::npos) << r.output;
  // Unknown formats.
  store = fresh("e");
  sql(store, "UPDATE campaign SET value = '99' WHERE key = 'format'");
  r = ncosim(fmt::format("export {}", quote(at("e"))));
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("store format '99' (this ncosim reads formats 1 to 3)"),
            std::string::npos)
      << r.output;
}

// Finding 7: every field of the campaign table that the commands read is checked, and a bad one
// is named (exit 2), never a bare `stoull` / `map::at` / JSON parser message or a silently
// different campaign.
TEST_F(StoreIntegrity, DamagedCampaignFieldsAreNamed) {
  ASSERT_EQ(ncosim(run_cmd(at("a"), 1)).code, 0);
  const std::vector<std::tuple<std::string, std::string, std::string>> cases{
      {"override_periods", "'0'", "campaign field 'override_periods'"},
      {"override_runs", "'x'", "campaign field 'override_runs'"},
      {"seed", "'-1'", "campaign field 'seed'"},
      {"runs", "'7'", "campaign field 'runs' is '7'"},
      {"periods", "'3000'", "campaign field 'periods' is '3000'"},
      {"overrides", "'[1,'", "campaign field 'overrides'"},
      {"inputs", "'[]'", "campaign field 'inputs'"},
      {"wall_seconds", "'nan'", "campaign field 'wall_seconds'"},
      {"threads", "''", "campaign field 'threads'"},
      {"shard", "'3/2'", "campaign field 'shard'"},
      {"target_ci", "'2'", "campaign field 'target_ci'"},
      {"scenario_hash", "'zz'", "campaign field 'scenario_hash'"},
  };
  for (const auto& [key, value, expected] : cases) {
    fs::remove_all(at("b"));
    fs::create_directories(at("b"));
    fs::copy_file(at("a/runs.sqlite"), at("b/runs.sqlite"));
    sql(at("b/runs.sqlite"),
        fmt::format("UPDATE campaign SET value = {} WHERE key = '{}'", value, key));
    const auto r = ncosim(fmt::format("export {}", quote(at("b"))));
    EXPECT_EQ(r.code, 2) << key << ": " << r.output;
    EXPECT_NE(r.output.find(expected), std::string::npos) << key << ": " << r.output;
  }
  // A missing field.
  fs::remove_all(at("b"));
  fs::create_directories(at("b"));
  fs::copy_file(at("a/runs.sqlite"), at("b/runs.sqlite"));
  sql(at("b/runs.sqlite"), "DELETE FROM campaign WHERE key = 'scenario_text'");
  auto r = ncosim(fmt::format("export {}", quote(at("b"))));
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("campaign field 'scenario_text': expected a value, got nothing"),
            std::string::npos)
      << r.output;
  // Finding 14: a stored text that does not load is reported as the store's, not the file's.
  fs::remove_all(at("b"));
  fs::create_directories(at("b"));
  fs::copy_file(at("a/runs.sqlite"), at("b/runs.sqlite"));
  sql(at("b/runs.sqlite"),
      "UPDATE campaign SET value = 'title = \"x\"' || char(10) || '[run' WHERE key = "
      "'scenario_text'");
  r = ncosim(fmt::format("export {}", quote(at("b"))));
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("the scenario text stored in it"), std::string::npos) << r.output;
}

// Finding 8: reading a store never writes it: a store that cannot be written (an immutable file:
// chattr +i, which binds root too) exports and merges, and leaves no -wal or -shm behind. Where
// the filesystem has no immutable flag, a read-only bind of the folder is not available to a test
// either, and the test says so.
TEST_F(StoreIntegrity, ReadingAStoreNeverWritesIt) {
  ASSERT_EQ(ncosim(run_cmd(at("a"), 1)).code, 0);
  const std::string store = at("a/runs.sqlite");
  const auto chattr = run_shell(fmt::format("chattr +i {} 2>&1", quote(store)));
  if (chattr.code != 0) GTEST_SKIP() << "no immutable flag on this filesystem: " << chattr.output;
  struct Unset {
    std::string path;
    ~Unset() { run_shell(fmt::format("chattr -i '{}'", path)); }
  } unset{store};
  auto r = ncosim(fmt::format("export {} --out {}", quote(at("a")), quote(at("b"))));
  EXPECT_EQ(r.code, 0) << r.output;
  r = ncosim(fmt::format("merge {} {}", quote(at("m")), quote(at("a"))));
  EXPECT_EQ(r.code, 0) << r.output;
  EXPECT_FALSE(fs::exists(store + "-wal"));
  EXPECT_FALSE(fs::exists(store + "-shm"));
  EXPECT_EQ(read_text(at("b/runs.csv")), read_text(at("a/runs.csv")));
  EXPECT_EQ(read_text(at("m/runs.csv")), read_text(at("a/runs.csv")));
  // What is not a store is still called so; what cannot be read says why.
  fs::create_directories(at("junk"));
  write(at("junk/runs.sqlite"),
        "not a database, not at all, but long enough to be read as a header....");
  r = ncosim(fmt::format("export {}", quote(at("junk"))));
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("is not an ncosim run store"), std::string::npos) << r.output;
}

// Finding 14: on the fallback path (no RENAME_EXCHANGE), a kill between moving the previous set
// aside and renaming the new one in, followed by a `run` that is itself killed at its first step,
// must not lose the previous set.
TEST_F(StoreIntegrity, TheFallbackSwapNeverLosesThePreviousSet) {
  const std::string out = at("out");
  ASSERT_EQ(ncosim(run_cmd(out, 1)).code, 0);
  const std::string runs1 = read_text(out + "/runs.csv");
  // Find the step "rename the new folder" of the fallback sequence.
  // (into a folder that exists: the swap is only needed then).
  ASSERT_EQ(ncosim(run_cmd(at("probe"), 1)).code, 0);
  const auto steps = ncosim(run_cmd(at("probe"), 2, " --replace"),
                            "NCOSIM_TEST_NO_EXCHANGE=1 NCOSIM_TEST_OUTPUT_STEPS=1 ");
  std::smatch m;
  ASSERT_TRUE(
      std::regex_search(steps.output, m, std::regex("output step ([0-9]+): rename the new folder")))
      << steps.output;
  const int rename_step = std::stoi(m[1]);
  auto r = ncosim(run_cmd(out, 2, " --replace"),
                  fmt::format("NCOSIM_TEST_NO_EXCHANGE=1 NCOSIM_TEST_KILL_AT={} ", rename_step));
  ASSERT_NE(r.code, 0) << r.output;
  ASSERT_FALSE(fs::exists(out)) << "the kill should leave the previous set moved aside";
  // The next writer is a run, killed at the first step of its own write.
  r = ncosim(run_cmd(out, 3, " --replace"), "NCOSIM_TEST_NO_EXCHANGE=1 NCOSIM_TEST_KILL_AT=1 ");
  ASSERT_NE(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("restored the previous result set"), std::string::npos) << r.output;
  ASSERT_TRUE(fs::exists(out + "/runs.csv"));
  EXPECT_EQ(read_text(out + "/runs.csv"), runs1);
  expect_store_and_exports_agree(out, at("check"), "after the fallback recovery");
}

// Finding 6's probe, kept: 8 random bytes overwritten at a random offset of a 40-run store, 80
// times (fixed seed). Each export must either refuse (exit 2, naming what is damaged) or give
// exactly the original exports (the bytes fell where nothing is read: free space, the readable
// copy of the metrics, the campaign fields the exports do not show); never different results
// with exit 0, never a crash.
TEST_F(StoreIntegrity, RandomOverwritesNeverChangeResultsSilently) {
  ASSERT_EQ(ncosim(fmt::format("run {} --out {} --runs 40 --periods 300 --no-timing --quiet",
                               quote(kBase.string()), quote(at("a"))))
                .code,
            0);
  const std::string original = at("a/runs.sqlite");
  const auto size = fs::file_size(original);
  std::mt19937_64 rng(29);
  int refused = 0, same = 0, changed = 0, other = 0;
  for (int trial = 0; trial < 80; ++trial) {
    fs::remove_all(at("b"));
    fs::create_directories(at("b"));
    fs::copy_file(original, at("b/runs.sqlite"));
    {
      std::fstream f(at("b/runs.sqlite"), std::ios::in | std::ios::out | std::ios::binary);
      f.seekp(static_cast<std::streamoff>(rng() % (size - 8)));
      for (int i = 0; i < 8; ++i) f.put(static_cast<char>(rng() & 0xFF));
    }
    const auto r = ncosim(fmt::format("export {} --out {}", quote(at("b")), quote(at("c"))));
    if (r.code == 2) {
      ++refused;
      EXPECT_NE(r.output.find("ncosim: "), std::string::npos) << r.output;
      continue;
    }
    if (r.code != 0) {
      ++other;
      ADD_FAILURE() << "trial " << trial << ": exit " << r.code << ": " << r.output;
      continue;
    }
    bool identical = true;
    for (const auto& f : kExports)
      identical = identical && comparable(at("a/" + f)) == comparable(at("c/" + f));
    (identical ? same : changed)++;
    EXPECT_TRUE(identical) << "trial " << trial << ": exit 0 with different exports";
  }
  std::cout << fmt::format(
      "random overwrites: {} refused, {} harmless, {} changed results, {} other\n", refused, same,
      changed, other);
  EXPECT_EQ(changed, 0);
  EXPECT_GE(refused, 20) << "the overwrites should mostly land in the runs";
}

// "Disk full" at many points of run, merge and export (the file-size limit of the process, with
// SIGXFSZ ignored, makes writes fail with EFBIG as a full disk makes them fail with ENOSPC): the
// command fails with exit 1 and a message, and the folder keeps its previous set, whose store and
// exports agree.
TEST_F(StoreIntegrity, AFullDiskAtAnyPointLeavesThePreviousSet) {
  const std::string out = at("out");
  ASSERT_EQ(ncosim(run_cmd(at("s1"), 2, " --shard 1/2")).code, 0);
  ASSERT_EQ(ncosim(run_cmd(at("s2"), 2, " --shard 2/2")).code, 0);
  ASSERT_EQ(ncosim(run_cmd(at("ref2"), 2)).code, 0);
  const std::vector<std::pair<std::string, std::string>> commands{
      {"run", run_cmd(out, 2, " --replace")},  // replaces the seed-1 campaign deliberately
      {"merge",
       fmt::format("merge {} {} {} --replace", quote(out), quote(at("s1")), quote(at("s2")))},
      {"export", fmt::format("export {} --out {} --replace", quote(at("ref2")), quote(out))},
  };
  int points = 0;
  for (const auto& [name, cmd] : commands) {
    for (int kb : {1, 4, 8, 16, 24, 32, 48, 64, 96, 128, 192}) {
      fs::remove_all(out);  // a killed run's unfinished store beside it is replaced deliberately
      ASSERT_EQ(ncosim(run_cmd(out, 1, " --replace")).code, 0);
      const std::string runs1 = read_text(out + "/runs.csv");
      const auto r =
          run_shell(fmt::format("trap '' XFSZ; ulimit -f {}; {} {}", kb, quote(kBinary), cmd));
      if (r.code == 0) continue;  // the limit was above what the command writes
      ++points;
      const std::string what = fmt::format("{} with {} KiB", name, kb);
      EXPECT_EQ(r.code, 1) << what << ": " << r.output;
      EXPECT_NE(r.output.find("ncosim: error: "), std::string::npos) << what << ": " << r.output;
      EXPECT_EQ(read_text(out + "/runs.csv"), runs1) << what;
      expect_store_and_exports_agree(out, at("check"), what);
    }
  }
  EXPECT_GE(points, 15);
}

}  // namespace
