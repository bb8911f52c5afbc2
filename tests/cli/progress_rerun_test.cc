// tests/cli/progress_rerun_test.cc — issue 28, parts 2 and 3, driven as a user does: a sweep with
// stderr to a file prints progress lines of the one format and a closing line with the right
// numbers; a re-run into a folder whose store holds runs of a different or unfinished campaign
// is refused (exit 2, the store byte-identical) unless --replace, and the same finished campaign
// re-runs as before.
#include <fcntl.h>
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <string>
#include <thread>
#include <vector>

#include "sim/store/store.h"
#include "spawn_ncosim.h"
#include "temp_dir_test.h"
#include "test_util.h"

extern char** environ;

namespace {

namespace fs = std::filesystem;
using ncosim::testing::read_text;
using ncosim::testing::run_shell;
using ncosim::testing::shell_quote;
using ncosim::testing::split_lines;

const std::string kBinary = NCOSIM_BINARY;
const fs::path kBase = fs::path(NCOSIM_SOURCE_DIR) / "tests" / "cli" / "data" / "base.toml";
const std::string kSweep = "\n[[sweep]]\nkey = \"estimator[0].history\"\nvalues = [1, 2, 3]\n";

class ProgressRerun : public ncosim::testing::TempDirTest {
 protected:
  ProgressRerun() : TempDirTest("ncosim_rerun_") {}
  std::string out() const { return (dir_ / "o").string(); }
  // `ncosim run FILE --out o ARGS`, stdout and stderr together.
  ncosim::testing::CommandOutcome run(const std::string& file, const std::string& args) {
    return run_shell(fmt::format("{} run {} --out {} {}", shell_quote(kBinary), shell_quote(file),
                                 shell_quote(out()), args));
  }
  // Every file of the folder and the store beside it, with its bytes.
  std::map<std::string, std::string> snapshot() const {
    std::map<std::string, std::string> files;
    for (const auto& e : fs::directory_iterator(dir_)) {
      // The store beside the folder (the lock file .o.lock holds the pid of its last holder).
      if (e.path().filename().string().rfind(".o.partial", 0) != 0) continue;
      if (e.is_regular_file()) files[e.path().filename().string()] = read_text(e.path().string());
    }
    for (const auto& e : fs::directory_iterator(out()))
      files["o/" + e.path().filename().string()] = read_text(e.path().string());
    return files;
  }
};

// A 3-case sweep of a few seconds with stderr to a file: every stderr line is a progress line of
// the one format over the campaign's 60 runs, at least one is there (2 s after the start), and
// stdout ends with the closing line.
TEST_F(ProgressRerun, ASweepLogsTheOneProgressFormatAndAClosingLineWithTheRightNumbers) {
  const std::string file = write("s.toml", read_text(kBase.string()) + kSweep);
  const std::string err = (dir_ / "err.txt").string();
  const auto t0 = std::chrono::steady_clock::now();
  const auto o = run_shell(
      fmt::format("( {} run {} --out {} --runs 20 --periods 60000 --threads 2 --no-timing 2>{} )",
                  shell_quote(kBinary), shell_quote(file), shell_quote(out()), shell_quote(err)));
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  ASSERT_EQ(o.code, 0) << o.output;
  const std::regex line(
      R"(ncosim: case [123]/3, \d+/60 runs, [0-9.]+ runs/s, elapsed \w+, ETA \w+)");
  const auto lines = split_lines(read_text(err));
  for (const auto& l : lines) EXPECT_TRUE(std::regex_match(l, line)) << l;
  if (wall > 2.5) {
    EXPECT_GE(lines.size(), 1u) << "no progress line in " << wall << " s";
  }
  const auto out_lines = split_lines(o.output);
  ASSERT_FALSE(out_lines.empty());
  const std::regex closing(
      "ncosim: 3 cases x 20 runs x 60000 periods = 60 runs in [0-9.]+ s: design [0-9.]+ s, "
      "simulation [0-9.]+ s on 2 threads; results in " +
      std::regex_replace(out(), std::regex(R"([.^$|()\[\]{}*+?\\])"), R"(\$&)") + "/");
  EXPECT_TRUE(std::regex_match(out_lines.back(), closing)) << out_lines.back();
  // Resumed: the runs stored before are said, and the campaign's total is the same.
  const auto r = run(file, "--runs 20 --periods 60000 --threads 1 --no-timing --resume --quiet");
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_NE(
      r.output.find(
          "ncosim: 3 cases x 20 runs x 60000 periods = 60 runs (60 stored before, 0 simulated now) "
          "in "),
      std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find(" on 1 thread; "), std::string::npos) << r.output;
}

TEST_F(ProgressRerun, ADifferentScenarioIsRefusedAndTheStoreLeftByteIdenticalUnlessReplace) {
  const std::string file = write("s.toml", read_text(kBase.string()));
  const std::string flags = "--runs 3 --periods 300 --quiet --no-timing";
  ASSERT_EQ(run(file, flags).code, 0);
  const auto before = snapshot();
  std::ofstream(file, std::ios::app) << "# an edit\n";
  auto r = run(file, flags);
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("--out: '" + out() + "' holds 3 finished run(s) of a different campaign"),
            std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find("the scenario text (hash"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("`--replace` starts afresh and replaces them"), std::string::npos)
      << r.output;
  EXPECT_EQ(r.output.find("--resume"), std::string::npos)
      << r.output;  // it cannot continue another campaign
  EXPECT_EQ(snapshot(), before);
  // Another --runs is another campaign too.
  r = run(file, "--runs 4 --periods 300 --quiet --no-timing");
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("--runs ('3' vs '4')"), std::string::npos) << r.output;
  EXPECT_EQ(snapshot(), before);
  // --replace replaces it, and says so.
  r = run(file, "--runs 4 --periods 300 --quiet --no-timing --replace");
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("--replace: replacing 3 finished run(s) of a different campaign"),
            std::string::npos)
      << r.output;
  EXPECT_EQ(ncosim::sim::RunStore::open(ncosim::sim::store_path(out()), false).count_runs(), 4);
  // Not with --resume: exit 2 before anything is read or written.
  fs::remove_all(out());
  r = run(file, flags + " --replace --resume");
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("--replace: not with --resume"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(out()));
}

TEST_F(ProgressRerun, TheSameFinishedCampaignReRunsAsBefore) {
  const std::string file = write("s.toml", read_text(kBase.string()) + kSweep);
  const std::string flags = "--runs 3 --periods 300 --quiet --no-timing";
  ASSERT_EQ(run(file, flags).code, 0);
  const std::string summary = read_text(out() + "/summary.csv");
  const auto r = run(file, flags + " --threads 1");
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_EQ(r.output.find("--replace"), std::string::npos) << r.output;
  EXPECT_EQ(read_text(out() + "/summary.csv"), summary);
}

// Starts ncosim with `args` (stdout and stderr to `log`); returns its pid (as in
// tests/cli/store_cli_test.cc).
pid_t spawn(const std::vector<std::string>& args, const std::string& log) {
  return ncosim::testing::spawn_ncosim(args, log);
}

std::int64_t stored_runs(const std::string& store) {
  try {
    return ncosim::sim::RunStore::open(store, false).count_runs();
  } catch (const std::exception&) {
    return -1;
  }
}

// The command of a killed campaign, run again without --resume: refused (it names --resume), the
// unfinished store byte-identical; --resume then finishes it.
TEST_F(ProgressRerun, AKilledCampaignReRunWithoutResumeIsRefused) {
  ::setenv("NCOSIM_TEST_COMMIT_MS", "10", 1);  // commits every 10 ms: the kill finds runs stored
  const std::string file = write("s.toml", read_text(kBase.string()));
  const std::vector<std::string> flags{"--runs",      "1500",      "--periods", "400",
                                       "--no-timing", "--threads", "2",         "--quiet"};
  std::vector<std::string> args{"run", file, "--out", out()};
  args.insert(args.end(), flags.begin(), flags.end());
  const pid_t pid = spawn(args, (dir_ / "log").string());
  ASSERT_GT(pid, 0);
  const std::string partial = ncosim::sim::partial_store_path(out());
  const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (stored_runs(partial) <= 0 && std::chrono::steady_clock::now() < until) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  ::kill(pid, SIGKILL);
  int status = 0;
  ::waitpid(pid, &status, 0);
  ::unsetenv("NCOSIM_TEST_COMMIT_MS");
  const std::int64_t n = stored_runs(partial);
  if (n <= 0 || n >= 1500)
    GTEST_SKIP() << "the kill did not hit the campaign (" << n << " runs stored)";
  const std::string bytes = read_text(partial);
  std::string cmd = "--runs 1500 --periods 400 --no-timing --threads 2 --quiet";
  auto r = run(file, cmd);
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find(
                fmt::format("holds {} finished run(s) of an unfinished campaign ({})", n, partial)),
            std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find("`--resume` continues it, `--replace` starts afresh"), std::string::npos)
      << r.output;
  EXPECT_EQ(read_text(partial), bytes);
  EXPECT_FALSE(fs::exists(out() + "/summary.csv"));
  r = run(file, cmd + " --resume");
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find(fmt::format("({} stored before, {} simulated now)", n, 1500 - n)),
            std::string::npos)
      << r.output;
}

}  // namespace
