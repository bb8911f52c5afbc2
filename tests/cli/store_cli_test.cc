// tests/cli/store_cli_test.cc — campaigns that survive and scale out, driven as a user does:
// the run store and `ncosim export`, SIGTERM/SIGINT (partial exports, exit 130/143), SIGKILL at
// random moments (integrity, exports that agree with the store, bit-identical resume),
// refusal to resume a different campaign, --shard + `ncosim merge` bit-identical to one
// process (flagship and a sweep), and the refusals of merge.
#include <fcntl.h>
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <spawn.h>
#include <sqlite3.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>
#include <regex>
#include <string>
#include <thread>
#include <vector>

#include "sim/store/store.h"
#include "spawn_ncosim.h"
#include "test_util.h"

extern char** environ;

namespace {

namespace fs = std::filesystem;
using ncosim::testing::read_text;
using ncosim::testing::run_shell;

const std::string kBinary = NCOSIM_BINARY;
const fs::path kSource = NCOSIM_SOURCE_DIR;
const fs::path kBase = kSource / "tests" / "cli" / "data" / "base.toml";
const fs::path kFlagship = kSource / "scenarios" / "dolz2014_table2.toml";

struct TempDir {
  fs::path path;
  explicit TempDir(const std::string& name)
      : path(fs::temp_directory_path() /
             ("ncosim_storecli_" + name + "_" + std::to_string(::getpid()))) {
    fs::remove_all(path);
    fs::create_directories(path);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
  std::string operator/(const std::string& rel) const { return (path / rel).string(); }
};

std::string quote(const std::string& s) { return "'" + s + "'"; }

std::string join(const std::vector<std::string>& args) {
  std::string out;
  for (const auto& a : args) out += (out.empty() ? "" : " ") + quote(a);
  return out;
}

ncosim::testing::CommandOutcome ncosim(const std::string& args) {
  return run_shell(quote(kBinary) + " " + args);
}

// The exports that must be bit-identical (timing aside: --no-timing, and design.json without
// its design_seconds lines).
const std::vector<std::string> kExports{"summary.csv",       "summary.md",    "runs.csv",
                                        "transmissions.csv", "confusion.csv", "trajectory.csv",
                                        "design.json",       "links.csv"};

std::string comparable(const fs::path& file) {
  if (!fs::exists(file)) return "<absent>";
  std::string text = read_text(file.string());
  if (file.filename() == "design.json")
    text = std::regex_replace(text, std::regex(".*design_seconds.*\n"), "");
  return text;
}

void expect_same_exports(const std::string& a, const std::string& b, const std::string& what) {
  // links.csv is compared, never absent on both sides (every scenario here has links).
  if (fs::exists(fs::path(a) / "summary.csv")) {
    EXPECT_TRUE(fs::exists(fs::path(a) / "links.csv")) << what;
  }
  for (const auto& f : kExports) {
    EXPECT_EQ(comparable(fs::path(a) / f), comparable(fs::path(b) / f))
        << what << ": " << f << " differs";
  }
}

// Starts ncosim with `args` (stdout and stderr to `log`); returns its pid.
pid_t spawn(const std::vector<std::string>& args, const std::string& log) {
  return ncosim::testing::spawn_ncosim(args, log);
}

int wait_exit(pid_t pid) {
  int status = 0;
  ::waitpid(pid, &status, 0);
  if (WIFEXITED(status)) return WEXITSTATUS(status);
  if (WIFSIGNALED(status)) return -WTERMSIG(status);
  return -1000;
}

// The store a campaign into `dir` is writing: beside the folder until its set is swapped in.
std::string live_store(const std::string& dir) {
  const std::string partial = ncosim::sim::partial_store_path(dir);
  return fs::exists(partial) ? partial : ncosim::sim::store_path(dir);
}

std::int64_t stored_runs(const std::string& dir) {
  try {
    const auto s = ncosim::sim::RunStore::open(live_store(dir), false);
    return s.count_runs();
  } catch (const std::exception&) {
    return -1;
  }
}

TEST(StoreCli, ExportReDerivesEveryFileFromTheStoreAlone) {
  TempDir t("export");
  // The scenario is copied, run, then deleted: the store alone must suffice.
  fs::copy_file(kBase, t / "scenario.toml");
  auto r = ncosim(fmt::format("run {} --out {} --runs 6 --no-timing --trace --quiet",
                              quote(t / "scenario.toml"), quote(t / "a")));
  ASSERT_EQ(r.code, 0) << r.output;
  ASSERT_TRUE(fs::exists(t / "a/runs.sqlite"));
  EXPECT_FALSE(fs::exists(t / "a/runs.sqlite-wal"))
      << "the store is checkpointed before the exports";
  fs::remove(t / "scenario.toml");
  fs::create_directories(t / "b");
  fs::copy_file(t / "a/runs.sqlite", t / "b/runs.sqlite");
  r = ncosim(fmt::format("export {}", quote(t / "b")));
  ASSERT_EQ(r.code, 0) << r.output;
  expect_same_exports(t / "a", t / "b", "export");
  EXPECT_TRUE(fs::exists(t / "b/trajectory.csv"));
  const auto man = nlohmann::json::parse(read_text(t / "b/manifest.json"));
  EXPECT_EQ(man["complete"], true);
  EXPECT_EQ(man["runs_done"], 6);
  // The readable columns agree with runs.csv's.
  const auto s = ncosim::sim::RunStore::open(ncosim::sim::store_path(t / "a"), false);
  EXPECT_EQ(s.integrity_check(), "ok");
  // Bad input: no store.
  r = ncosim(fmt::format("export {}", quote(t.path.string())));
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("no run store"), std::string::npos) << r.output;
}

// Drops the link counters' table: the store then looks like one written before link counting.
void drop_link_table(const fs::path& store) {
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(store.c_str(), &db), SQLITE_OK);
  EXPECT_EQ(sqlite3_exec(db, "DROP TABLE link_runs", nullptr, nullptr, nullptr), SQLITE_OK);
  sqlite3_close(db);
}

TEST(StoreCli, AStoreWithoutLinkCountersExportsEverythingButLinksCsvAndSaysSo) {
  TempDir t("oldstore");
  const std::string flags = "--runs 6 --periods 400 --no-timing --quiet";
  auto r = ncosim(fmt::format("run {} --out {} {}", quote(kBase.string()), quote(t / "a"), flags));
  ASSERT_EQ(r.code, 0) << r.output;
  fs::create_directories(t / "b");
  fs::copy_file(t / "a/runs.sqlite", t / "b/runs.sqlite");
  drop_link_table(t / "b/runs.sqlite");
  r = ncosim(fmt::format("export {}", quote(t / "b")));
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_FALSE(fs::exists(t / "b/links.csv"));
  for (const auto& f : kExports) {
    if (f == "links.csv") continue;
    EXPECT_EQ(comparable(fs::path(t / "a") / f), comparable(fs::path(t / "b") / f))
        << f << " differs";
  }
  auto man = nlohmann::json::parse(read_text(t / "b/manifest.json"));
  EXPECT_EQ(man["links_csv"],
            "not written: 6 of the 6 stored runs have no link counters (a store written before "
            "ncosim counted them)");
  // An earlier links.csv in the folder does not survive an export that cannot write one.
  fs::copy_file(t / "a/links.csv", t / "b/links.csv");
  ASSERT_EQ(ncosim(fmt::format("export {}", quote(t / "b"))).code, 0);
  EXPECT_FALSE(fs::exists(t / "b/links.csv"));
  // Merged with a shard that counted them: some runs still lack counters, so no links.csv.
  const fs::path part = t / "part";
  r = ncosim(fmt::format("run {} --out {} --runs 6 --periods 400 --no-timing --quiet --shard 1/2",
                         quote(kBase.string()), quote(part)));
  ASSERT_EQ(r.code, 0) << r.output;
  drop_link_table(part / "runs.sqlite");
  r = ncosim(fmt::format("run {} --out {} --runs 6 --periods 400 --no-timing --quiet --shard 2/2",
                         quote(kBase.string()), quote(t / "part2")));
  ASSERT_EQ(r.code, 0) << r.output;
  r = ncosim(fmt::format("merge {} {} {}", quote(t / "m"), quote(part), quote(t / "part2")));
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_FALSE(fs::exists(t / "m/links.csv"));
  man = nlohmann::json::parse(read_text(t / "m/manifest.json"));
  EXPECT_EQ(man["links_csv"],
            "not written: 3 of the 6 stored runs have no link counters (a store written before "
            "ncosim counted them)");
  EXPECT_EQ(comparable(t / "a/runs.csv"), comparable(t / "m/runs.csv"));
}

// A campaign long enough to be interrupted (about a second on 2 threads).
const std::vector<std::string> kLong{"--runs",      "1500",      "--periods", "400",
                                     "--no-timing", "--threads", "2",         "--quiet"};

// Batches committed every 10 ms instead of 250 ms while alive: the signal tests wait for the
// first commit, and on a fast machine the whole campaign takes little more than one default
// interval (CI once signalled after the last run, 1.4 s for both campaigns).
struct CommitEvery10ms {
  CommitEvery10ms() { ::setenv("NCOSIM_TEST_COMMIT_MS", "10", 1); }
  ~CommitEvery10ms() { ::unsetenv("NCOSIM_TEST_COMMIT_MS"); }
  CommitEvery10ms(const CommitEvery10ms&) = delete;
  CommitEvery10ms& operator=(const CommitEvery10ms&) = delete;
};

TEST(StoreCli, SigtermAndSigintCommitFinishedRunsWritePartialExportsAndResumeCompletes) {
  TempDir t("sigterm");
  const CommitEvery10ms commit_every_10ms;
  auto args = [&](const std::string& out, std::vector<std::string> extra = {}) {
    std::vector<std::string> a{"run", kBase.string(), "--out", out};
    a.insert(a.end(), kLong.begin(), kLong.end());
    a.insert(a.end(), extra.begin(), extra.end());
    return a;
  };
  auto ref = ncosim(join(args(t / "ref")));
  ASSERT_EQ(ref.code, 0) << ref.output;
  for (const auto& [sig, code, name] :
       {std::tuple{SIGTERM, 143, "SIGTERM"}, std::tuple{SIGINT, 130, "SIGINT"}}) {
    const std::string out = t / name;
    const pid_t pid = spawn(args(out), t / "log");
    ASSERT_GT(pid, 0);
    // Wait for the first committed runs, then signal.
    const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(60);
    while (stored_runs(out) <= 0 && std::chrono::steady_clock::now() < until) {
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    ::kill(pid, sig);
    const int exit = wait_exit(pid);
    const std::string log = read_text(t / "log");
    if (exit == 0) {  // finished before the signal arrived (a very fast machine): nothing to check
      GTEST_SKIP() << "campaign finished before " << name;
    }
    ASSERT_EQ(exit, code) << log;
    if (stored_runs(out) ==
        1500) {  // the signal came after the last run: a complete campaign, said so
      EXPECT_NE(log.find(std::string(name) +
                         " stopped nothing (every run had started): the campaign is complete"),
                std::string::npos)
          << log;
      const auto man = nlohmann::json::parse(read_text(fs::path(out) / "manifest.json"));
      EXPECT_EQ(man["complete"], true);
      EXPECT_EQ(man["stopped"], name);
      EXPECT_EQ(read_text(fs::path(out) / "summary.md").find("Partial results"), std::string::npos);
      expect_same_exports(t / "ref", out, std::string("late ") + name);
      continue;
    }
    EXPECT_NE(log.find(std::string("stopped by ") + name), std::string::npos) << log;
    const auto man = nlohmann::json::parse(read_text(fs::path(out) / "manifest.json"));
    EXPECT_EQ(man["complete"], false);
    EXPECT_EQ(man["stopped"], name);
    const std::int64_t done = man["runs_done"].get<std::int64_t>();
    EXPECT_GT(done, 0);
    EXPECT_LT(done, 1500);
    EXPECT_EQ(stored_runs(out), done);
    EXPECT_NE(read_text(fs::path(out) / "summary.md").find("Partial results"), std::string::npos);
    const auto r = ncosim(join(args(out, {"--resume"})));
    ASSERT_EQ(r.code, 0) << r.output;
    expect_same_exports(t / "ref", out, std::string("resume after ") + name);
    EXPECT_EQ(nlohmann::json::parse(read_text(fs::path(out) / "manifest.json"))["complete"], true);
  }
}

// A signal after the last run stops nothing: complete exports, said so, the signal's status.
TEST(StoreCli, ASignalAfterTheLastRunLeavesACompleteCampaign) {
  TempDir t("late");
  const std::string flags = "--runs 6 --periods 400 --no-timing --quiet";
  auto ref =
      ncosim(fmt::format("run {} --out {} {}", quote(kBase.string()), quote(t / "ref"), flags));
  ASSERT_EQ(ref.code, 0) << ref.output;
  auto r = run_shell(fmt::format("NCOSIM_TEST_RAISE_AFTER_RUNS={} {} run {} --out {} {}", SIGTERM,
                                 quote(kBinary), quote(kBase.string()), quote(t / "late"), flags));
  ASSERT_EQ(r.code, 143) << r.output;
  EXPECT_NE(
      r.output.find(
          "SIGTERM stopped nothing (every run had started): the campaign is complete (6 run(s)"),
      std::string::npos)
      << r.output;
  EXPECT_EQ(r.output.find("partial"), std::string::npos)
      << r.output;  // nor the handler's line, nor summary.md
  const auto man = nlohmann::json::parse(read_text(t / "late/manifest.json"));
  EXPECT_EQ(man["complete"], true);
  EXPECT_EQ(man["stopped"], "SIGTERM");
  EXPECT_EQ(read_text(t / "late/summary.md").find("Partial results"), std::string::npos);
  expect_same_exports(t / "ref", t / "late", "late SIGTERM");
}

TEST(StoreCli, SigkillAtRandomMomentsNeverCorruptsAndResumeIsBitIdentical) {
  TempDir t("kill");
  // Without the 10 ms commits, no kill could find a partly filled store on a fast machine.
  const CommitEvery10ms commit_every_10ms;
  const std::vector<std::string> small{"--runs",      "120",       "--periods", "1500",
                                       "--no-timing", "--threads", "2",         "--quiet"};
  std::string flags;
  for (const auto& a : small) flags += " " + a;
  const auto t0 = std::chrono::steady_clock::now();
  auto ref =
      ncosim(fmt::format("run {} --out {}{}", quote(kBase.string()), quote(t / "ref"), flags));
  const double total = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  ASSERT_EQ(ref.code, 0) << ref.output;
  std::mt19937 rng(13);  // fixed: the same kill moments every time (up to the machine's speed)
  std::uniform_real_distribution<double> when(0.0, 1.1 * total);
  int with_store = 0, mid_campaign = 0;
  for (int trial = 0; trial < 20; ++trial) {
    const std::string out = t / fmt::format("k{}", trial);
    std::vector<std::string> args{"run", kBase.string(), "--out", out};
    args.insert(args.end(), small.begin(), small.end());
    const pid_t pid = spawn(args, t / "log");
    ASSERT_GT(pid, 0);
    std::this_thread::sleep_for(std::chrono::duration<double>(when(rng)));
    ::kill(pid, SIGKILL);
    wait_exit(pid);
    // A killed campaign's store is beside the folder; the folder holds no set (the first campaign).
    const std::string store = live_store(out);
    bool resumable = false;
    if (fs::exists(store)) {
      ++with_store;
      try {
        const auto s = ncosim::sim::RunStore::open(store, false);
        EXPECT_EQ(s.integrity_check(), "ok") << "trial " << trial;
        const auto n = s.count_runs();
        if (n > 0 && n < 120) ++mid_campaign;
        // Every stored record reads back.
        EXPECT_NO_THROW((void)s.load_case(0)) << "trial " << trial;
        resumable = true;
      } catch (const ncosim::sim::StoreError& e) {
        // Killed while the store was being created: its campaign row may not be committed yet,
        // or its -journal is still hot (the kill landed inside a transaction), which a reader
        // cannot roll back and must say so (SQLite says "attempt to write a readonly database").
        const std::string why = e.what();
        EXPECT_TRUE(why.find("not an ncosim run store") != std::string::npos ||
                    why.find("was killed mid-write (its -journal holds a change only a writer "
                             "can undo); `ncosim run` with --resume undoes it") !=
                        std::string::npos)
            << why;
      }
    }
    if (fs::exists(fs::path(out) / "summary.csv")) {  // exports written: they agree with the store
      const auto r = ncosim(fmt::format("export {} --out {}", quote(out), quote(out + "_export")));
      ASSERT_EQ(r.code, 0) << r.output;
      expect_same_exports(out, out + "_export", fmt::format("trial {}: exports vs store", trial));
    }
    const auto r = ncosim(fmt::format("run {} --out {}{}{}", quote(kBase.string()), quote(out),
                                      flags, resumable ? " --resume" : ""));
    ASSERT_EQ(r.code, 0) << "trial " << trial << ": " << r.output;
    expect_same_exports(t / "ref", out, fmt::format("trial {}: resume", trial));
  }
  // The kill moments must have hit the campaign, not only its start or its end.
  EXPECT_GE(mid_campaign, 5) << with_store << " trials left a store";
}

TEST(StoreCli, ResumeRefusesADifferentCampaignNamingWhatDiffers) {
  TempDir t("refuse");
  fs::copy_file(kBase, t / "s.toml");
  const std::string base = fmt::format("run {} --out {} --runs 3 --periods 300 --quiet --no-timing",
                                       quote(t / "s.toml"), quote(t / "o"));
  auto r = ncosim(base + " --resume");
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("no run store to resume"), std::string::npos) << r.output;
  ASSERT_EQ(ncosim(base).code, 0);
  r = ncosim(base + " --resume");
  EXPECT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("3 runs x 300 periods (3 stored before, 0 simulated now) in "),
            std::string::npos)
      << r.output;
  for (const auto& [extra, what] :
       std::vector<std::pair<std::string, std::string>>{{" --seed 8", "--seed"},
                                                        {" --set run.warmup=50", "--set overrides"},
                                                        {" --shard 1/2", "--shard"}}) {
    r = ncosim(base + " --resume" + extra);
    EXPECT_EQ(r.code, 2) << extra << ": " << r.output;
    EXPECT_NE(r.output.find(what), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("different campaign"), std::string::npos) << r.output;
  }
  std::ofstream(t / "s.toml", std::ios::app) << "# an edit\n";
  r = ncosim(base + " --resume");
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("the scenario text"), std::string::npos) << r.output;
  // Bad shard syntax.
  r = ncosim(base + " --shard 3/2");
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("--shard: expected I/N"), std::string::npos) << r.output;
}

// Shards in several layouts, merged, against one process with --threads 1.
void check_shards(const std::string& scenario, const std::string& flags,
                  const std::vector<int>& layouts, const TempDir& t) {
  auto r = ncosim(
      fmt::format("run {} --out {} --threads 1 {}", quote(scenario), quote(t / "ref"), flags));
  ASSERT_EQ(r.code, 0) << r.output;
  for (int n : layouts) {
    std::string dirs;
    for (int i = 1; i <= n; ++i) {
      const std::string out = t / fmt::format("n{}_{}", n, i);
      r = ncosim(fmt::format("run {} --out {} --shard {}/{} --threads {} {}", quote(scenario),
                             quote(out), i, n, 1 + i % 2, flags));
      ASSERT_EQ(r.code, 0) << r.output;
      dirs += " " + quote(out);
    }
    const std::string merged = t / fmt::format("merged{}", n);
    r = ncosim(fmt::format("merge {}{}", quote(merged), dirs));
    ASSERT_EQ(r.code, 0) << r.output;
    expect_same_exports(t / "ref", merged, fmt::format("{} shards", n));
    EXPECT_EQ(nlohmann::json::parse(read_text(fs::path(merged) / "manifest.json"))["complete"],
              true);
  }
}

TEST(StoreCli, ShardsMergedAreBitIdenticalToOneProcessOnTheFlagship) {
  TempDir t("shards");
  check_shards(kFlagship.string(), "--runs 12 --periods 3000 --no-timing --quiet", {2, 3, 5}, t);
}

TEST(StoreCli, ShardsMergedAreBitIdenticalToOneProcessOnASweep) {
  TempDir t("sweep");
  std::ofstream(t / "sweep.toml") << read_text(kBase.string())
                                  << "\n[[sweep]]\nkey = \"link[1].loss\"\nvalues = [0.1, 0.4]\n"
                                     "\n[[sweep]]\nkey = \"run.seed\"\nvalues = [1, 2]\n";
  check_shards(t / "sweep.toml", "--runs 7 --periods 800 --no-timing --quiet", {3}, t);
}

TEST(StoreCli, MergeRefusesOverlapsGapsAndDifferentCampaigns) {
  TempDir t("merge_bad");
  const std::string base =
      fmt::format("run {} --runs 4 --periods 300 --quiet --no-timing", quote(kBase.string()));
  ASSERT_EQ(ncosim(base + " --shard 1/2 --out " + quote(t / "a")).code, 0);
  ASSERT_EQ(ncosim(base + " --shard 2/2 --out " + quote(t / "b")).code, 0);
  ASSERT_EQ(ncosim(base + " --shard 2/2 --seed 9 --out " + quote(t / "c")).code, 0);
  ASSERT_EQ(ncosim(base + " --out " + quote(t / "whole")).code, 0);
  auto r = ncosim(fmt::format("merge {} {} {}", quote(t / "m1"), quote(t / "a"), quote(t / "a")));
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("overlapping"), std::string::npos) << r.output;
  r = ncosim(fmt::format("merge {} {}", quote(t / "m2"), quote(t / "a")));
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("2 run(s) missing"), std::string::npos) << r.output;
  r = ncosim(fmt::format("merge {} {} {}", quote(t / "m3"), quote(t / "a"), quote(t / "c")));
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("different campaigns"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("--seed"), std::string::npos) << r.output;
  r = ncosim(fmt::format("merge {} {} {}", quote(t / "a"), quote(t / "a"), quote(t / "b")));
  EXPECT_EQ(r.code, 2) << r.output;
  r = ncosim(fmt::format("merge {} {} {}", quote(t / "m4"), quote(t / "a"), quote(t / "nothing")));
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_FALSE(fs::exists(t / "m1/summary.csv"));
  r = ncosim(fmt::format("merge {} {} {}", quote(t / "m5"), quote(t / "b"), quote(t / "a")));
  ASSERT_EQ(r.code, 0) << r.output;
  expect_same_exports(t / "whole", t / "m5", "merge in any order");
}

}  // namespace

namespace {

// summary.csv as rows of cells (no quoted commas in these files' estimator names but "S1, 1 gain"
// style ones: a minimal RFC 4180 reader).
std::vector<std::vector<std::string>> read_csv(const std::string& path) {
  std::vector<std::vector<std::string>> rows(1);
  std::string cell;
  bool quoted = false;
  const std::string text = read_text(path);
  for (std::size_t i = 0; i < text.size(); ++i) {
    const char ch = text[i];
    if (quoted) {
      if (ch == '"' && i + 1 < text.size() && text[i + 1] == '"') {
        cell += '"';
        ++i;
      } else if (ch == '"') {
        quoted = false;
      } else {
        cell += ch;
      }
    } else if (ch == '"') {
      quoted = true;
    } else if (ch == ',') {
      rows.back().push_back(cell);
      cell.clear();
    } else if (ch == '\n') {
      rows.back().push_back(cell);
      cell.clear();
      rows.emplace_back();
    } else {
      cell += ch;
    }
  }
  rows.pop_back();
  return rows;
}

std::size_t column(const std::vector<std::string>& head, const std::string& name) {
  return static_cast<std::size_t>(std::find(head.begin(), head.end(), name) - head.begin());
}

TEST(StoreCli, TargetCiStopsAtTheSameRunForAnyThreadsOrShardsAndEveryOkRowMeetsIt) {
  TempDir t("target");
  const double rel = 0.02;
  const std::string flags = fmt::format(
      "--runs 10 --periods 1000 --target-ci {} --max-runs 400 --no-timing --quiet", rel);
  const std::string file = quote(kBase.string());
  auto r = ncosim(fmt::format("run {} --out {} --threads 1 {}", file, quote(t / "one"), flags));
  ASSERT_EQ(r.code, 0) << r.output;
  r = ncosim(fmt::format("run {} --out {} --threads 2 {}", file, quote(t / "two"), flags));
  ASSERT_EQ(r.code, 0) << r.output;
  expect_same_exports(t / "one", t / "two", "--target-ci, 1 vs 2 threads");
  std::string dirs;
  for (int i = 1; i <= 3; ++i) {
    const std::string out = t / fmt::format("s{}", i);
    r = ncosim(fmt::format("run {} --out {} --shard {}/3 {}", file, quote(out), i, flags));
    ASSERT_EQ(r.code, 0) << r.output;
    dirs += " " + quote(out);
  }
  r = ncosim(fmt::format("merge {}{}", quote(t / "merged"), dirs));
  ASSERT_EQ(r.code, 0) << r.output;
  expect_same_exports(t / "one", t / "merged", "--target-ci, 3 shards merged");

  const auto rows = read_csv(t / "one/summary.csv");
  ASSERT_GT(rows.size(), 1u);
  const auto& head = rows[0];
  const std::size_t runs = column(head, "runs"), mse = column(head, "mse"),
                    ci = column(head, "mse_ci95"), status = column(head, "status"),
                    stop = column(head, "stop");
  ASSERT_LT(stop, head.size()) << "summary.csv has a stop column with --target-ci";
  const auto man = nlohmann::json::parse(read_text(t / "one/manifest.json"));
  const auto used = man["target_ci"]["runs"].get<std::int64_t>();
  EXPECT_EQ(man["target_ci"]["stop"], rows[1][stop]);
  EXPECT_EQ(used % 10, 0) << "whole batches";
  EXPECT_GE(used, 20);
  int ok = 0;
  for (std::size_t i = 1; i < rows.size(); ++i) {
    EXPECT_EQ(rows[i][runs], std::to_string(used));
    if (rows[i][status] != "ok") continue;
    ++ok;
    EXPECT_LE(std::stod(rows[i][ci]) / std::stod(rows[i][mse]), rel * (1 + 1e-5)) << rows[i][1];
  }
  EXPECT_EQ(rows[1][stop], "target_ci");  // reached well before --max-runs (60 runs when written)
  EXPECT_LT(used, 400);
  EXPECT_EQ(ok, static_cast<int>(rows.size()) - 1);
}

TEST(StoreCli, TargetCiNotReachedAtMaxRunsIsSaidInTheStatusAndBadOptionsAreRefused) {
  TempDir t("target_max");
  const std::string file = quote(kBase.string());
  auto r = ncosim(
      fmt::format("run {} --out {} --runs 5 --periods 300 --target-ci 0.0001 --max-runs 12 --quiet "
                  "--no-timing",
                  file, quote(t / "o")));
  ASSERT_EQ(r.code, 0) << r.output;
  const auto rows = read_csv(t / "o/summary.csv");
  const std::size_t stop = column(rows[0], "stop"), status = column(rows[0], "status"),
                    runs = column(rows[0], "runs");
  for (std::size_t i = 1; i < rows.size(); ++i) {
    EXPECT_EQ(rows[i][stop], "max_runs");
    EXPECT_EQ(rows[i][runs], "12");  // batches of 5, the last one cut at --max-runs
    EXPECT_EQ(rows[i][status], "ci_target_not_met");
  }
  EXPECT_NE(read_text(t / "o/summary.md").find("--max-runs 12"), std::string::npos);
  for (const auto& [args, what] : std::vector<std::pair<std::string, std::string>>{
           {"--target-ci 0.01", "--max-runs N is required"},
           {"--max-runs 50", "only with --target-ci"},
           {"--target-ci 0 --max-runs 50", "expected a relative half-width"},
           {"--target-ci 1.5 --max-runs 50", "expected a relative half-width"},
           {"--target-ci 0.01 --max-runs 3", "at least run.runs"}}) {
    r = ncosim(fmt::format("run {} --out {} --runs 5 --periods 300 --quiet {}", file,
                           quote(t / "bad"), args));
    EXPECT_EQ(r.code, 2) << args << ": " << r.output;
    EXPECT_NE(r.output.find(what), std::string::npos) << args << ": " << r.output;
  }
  EXPECT_FALSE(fs::exists(t / "bad"));
}

}  // namespace
