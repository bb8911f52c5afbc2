// tests/sim/output_set_test.cc — the atomic output set (sim/files/output_set.h): carry-over of
// foreign entries, the output-folder lock, and kills at every step of the write sequence and at
// random moments (fork + SIGKILL): a folder always holds the previous complete set or the new one.
#include "sim/files/output_set.h"

#include <gtest/gtest.h>
#include <signal.h>
#include <stdlib.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "config/config.h"
#include "test_util.h"

namespace ncosim::sim {
namespace {

namespace fs = std::filesystem;
using Files = std::vector<std::pair<std::string, std::string>>;

// On tmpfs when there is one: the kill tests check the sequence, not the disk, and fsync on a
// loaded disk would make them slow.
fs::path fresh_dir(const std::string& name) {
  std::error_code ec;
  const fs::path root = fs::is_directory("/dev/shm", ec) && ::access("/dev/shm", W_OK) == 0
                            ? fs::path("/dev/shm")
                            : fs::temp_directory_path();
  const fs::path p = root / ("ncosim_output_set_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(p);
  fs::create_directories(p);
  return p;
}

std::map<std::string, std::string> contents(const fs::path& dir) {
  std::map<std::string, std::string> m;
  for (const auto& e : fs::directory_iterator(dir))
    m[e.path().filename().string()] = testing::read_text(e.path().string());
  return m;
}

// Set `tag` (A or B): B drops trajectory.csv (stale) and adds confusion.csv.
Files make_set(char tag, std::size_t bytes) {
  Files f{{"summary.csv", std::string(bytes, tag)},
          {"runs.csv", std::string(bytes * 3, tag)},
          {"manifest.json", std::string(1, tag)}};
  f.emplace_back(tag == 'A' ? "trajectory.csv" : "confusion.csv", std::string(bytes / 2 + 1, tag));
  return f;
}
const std::vector<std::string> kStale{"trajectory.csv", "confusion.csv"};

// The folder holds exactly set `tag` plus the carried-over runs.sqlite.
bool holds(const fs::path& dir, char tag, std::size_t bytes) {
  auto want = std::map<std::string, std::string>();
  for (const auto& [n, c] : make_set(tag, bytes)) want[n] = c;
  want["runs.sqlite"] = "store";
  return contents(dir) == want;
}

// Everything next to the folder except the folder itself and its lock file.
std::vector<std::string> leftovers(const fs::path& parent, const std::string& name) {
  std::vector<std::string> out;
  for (const auto& e : fs::directory_iterator(parent)) {
    const std::string n = e.path().filename().string();
    if (n != name && n != "." + name + ".lock") out.push_back(n);
  }
  return out;
}

// Runs write_output_set in a child with the environment `env` set; returns the wait status.
int write_in_child(const fs::path& dir, const Files& files,
                   const std::vector<std::pair<std::string, std::string>>& env) {
  const pid_t pid = ::fork();
  if (pid == 0) {
    for (const auto& [k, v] : env) ::setenv(k.c_str(), v.c_str(), 1);
    int code = 0;
    try {
      write_output_set(dir.string(), files, kStale);
    } catch (...) {
      code = 3;
    }
    ::_exit(code);
  }
  int status = 0;
  ::waitpid(pid, &status, 0);
  return status;
}

TEST(OutputSet, WritesTheSetDropsStaleEntriesAndCarriesOverTheRest) {
  const fs::path parent = fresh_dir("carry");
  const fs::path dir = parent / "out";
  write_output_set(dir.string(), make_set('A', 10), kStale);
  std::ofstream(dir / "runs.sqlite") << "store";
  struct stat before {};
  ASSERT_EQ(::stat((dir / "runs.sqlite").c_str(), &before), 0);
  write_output_set(dir.string(), make_set('B', 10), kStale);
  EXPECT_TRUE(holds(dir, 'B', 10));
  struct stat after {};
  ASSERT_EQ(::stat((dir / "runs.sqlite").c_str(), &after), 0);
  EXPECT_EQ(before.st_ino, after.st_ino);  // the same file (an open database keeps writing to it)
  EXPECT_TRUE(leftovers(parent, "out").empty());
  fs::remove_all(parent);
}

TEST(OutputSet, OldPerFileTemporariesAreDroppedAndCounted) {
  const fs::path parent = fresh_dir("inner");
  const fs::path dir = parent / "out";
  fs::create_directories(dir);
  std::ofstream(dir / ".summary.csv.tmp12345") << "half";
  std::ofstream(dir / "runs.sqlite") << "store";
  EXPECT_EQ(write_output_set(dir.string(), make_set('A', 5), kStale), 1);
  EXPECT_TRUE(holds(dir, 'A', 5));
  fs::remove_all(parent);
}

TEST(OutputSet, RefusesTheCurrentFolderAndEmptyNames) {
  EXPECT_THROW(output_set_folder(""), config::ScenarioError);
  EXPECT_THROW(output_set_folder("."), config::ScenarioError);
  EXPECT_THROW(output_set_folder("/"), config::ScenarioError);
}

TEST(OutputSet, LockExcludesASecondProcessAndNamesItsPid) {
  const fs::path parent = fresh_dir("lock");
  const fs::path dir = parent / "out";
  int ready[2];
  int release[2];
  ASSERT_EQ(::pipe(ready), 0);
  ASSERT_EQ(::pipe(release), 0);
  const pid_t pid = ::fork();
  if (pid == 0) {
    OutputFolderLock lock(dir.string());
    char c = 'x';
    if (::write(ready[1], &c, 1) != 1) ::_exit(1);
    if (::read(release[0], &c, 1) != 1) ::_exit(1);
    ::_exit(0);
  }
  char c = 0;
  ASSERT_EQ(::read(ready[0], &c, 1), 1);
  try {
    OutputFolderLock second(dir.string());
    ADD_FAILURE() << "a second process took the lock";
  } catch (const config::ScenarioError& e) {
    EXPECT_NE(std::string(e.what()).find("PID " + std::to_string(pid)), std::string::npos)
        << e.what();
  }
  EXPECT_THROW(write_output_set(dir.string(), make_set('A', 3), kStale), config::ScenarioError);
  ASSERT_EQ(::write(release[1], &c, 1), 1);
  int status = 0;
  ::waitpid(pid, &status, 0);
  // Released with its holder: this process now takes it, re-entrantly.
  OutputFolderLock mine(dir.string());
  EXPECT_NO_THROW(write_output_set(dir.string(), make_set('A', 3), kStale));
  for (int fd : {ready[0], ready[1], release[0], release[1]}) ::close(fd);
  fs::remove_all(parent);
}

// Kills the writer just before every step of the sequence (and once after the last), in both
// directions (A -> B, B -> A), with the atomic exchange and with the fallback that moves the
// previous folder aside; after each kill the folder holds one complete set, and the next write
// cleans every temporary.
void kill_at_every_step(bool fallback, int& kills, int& mixed) {
  const fs::path parent = fresh_dir(fallback ? "kill_fallback" : "kill");
  const fs::path dir = parent / "out";
  const std::size_t bytes = 20000;
  write_output_set(dir.string(), make_set('A', bytes), kStale);
  std::ofstream(dir / "runs.sqlite") << "store";
  char current = 'A';
  for (int round = 0; round < 2; ++round) {
    const char next = current == 'A' ? 'B' : 'A';
    for (int k = 1;; ++k) {
      std::vector<std::pair<std::string, std::string>> env{
          {"NCOSIM_TEST_KILL_AT", std::to_string(k)}};
      if (fallback) env.emplace_back("NCOSIM_TEST_NO_EXCHANGE", "1");
      const int status = write_in_child(dir, make_set(next, bytes), env);
      const bool killed = WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL;
      if (!killed) {
        EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << "step " << k;
        EXPECT_TRUE(holds(dir, next, bytes));
        current = next;
        break;
      }
      ++kills;
      // A reader right after the kill (before any recovery) sees one set; with the fallback, a
      // kill between its two renames leaves no folder until the next writer restores it.
      const bool whole =
          fs::exists(dir) ? holds(dir, current, bytes) || holds(dir, next, bytes) : fallback;
      if (!whole) ++mixed;
      EXPECT_TRUE(whole) << "kill before step " << k;
      // The next writer restores/cleans, then writes `current` again.
      write_output_set(dir.string(), make_set(current, bytes), kStale);
      EXPECT_TRUE(holds(dir, current, bytes)) << "after recovery from a kill before step " << k;
      EXPECT_TRUE(leftovers(parent, "out").empty()) << "temporaries left after step " << k;
      ASSERT_LT(k, 100);
    }
  }
  fs::remove_all(parent);
}

TEST(OutputSet, KillAtEveryStepLeavesTheOldOrTheNewSet) {
  int kills = 0, mixed = 0;
  for (int rep = 0; rep < 3; ++rep) kill_at_every_step(false, kills, mixed);
  kill_at_every_step(true, kills, mixed);
  EXPECT_GE(kills, 100);
  EXPECT_EQ(mixed, 0);
  std::printf("injected kills: %d, mixed or partial sets: %d\n", kills, mixed);
}

TEST(OutputSet, RandomKillsLeaveTheOldOrTheNewSet) {
  const fs::path parent = fresh_dir("random");
  const fs::path dir = parent / "out";
  const std::size_t bytes = 200000;
  write_output_set(dir.string(), make_set('A', bytes), kStale);
  std::ofstream(dir / "runs.sqlite") << "store";
  std::mt19937 rng(18);
  int mixed = 0;
  for (int i = 0; i < 30; ++i) {
    const pid_t pid = ::fork();
    if (pid == 0) {
      for (int w = 0;; ++w) {
        try {
          write_output_set(dir.string(), make_set(w % 2 ? 'A' : 'B', bytes), kStale);
        } catch (...) {
          ::_exit(3);
        }
      }
    }
    std::this_thread::sleep_for(
        std::chrono::microseconds(std::uniform_int_distribution<int>(0, 20000)(rng)));
    ::kill(pid, SIGKILL);
    int status = 0;
    ::waitpid(pid, &status, 0);
    ASSERT_TRUE(WIFSIGNALED(status)) << "the writer stopped on its own";
    const bool whole = holds(dir, 'A', bytes) || holds(dir, 'B', bytes);
    if (!whole) ++mixed;
    EXPECT_TRUE(whole) << "kill " << i;
  }
  EXPECT_EQ(mixed, 0);
  write_output_set(dir.string(), make_set('A', bytes), kStale);
  EXPECT_TRUE(leftovers(parent, "out").empty());
  fs::remove_all(parent);
}

}  // namespace
}  // namespace ncosim::sim
