// tests/network/worker_test.cc — the network workers (network/worker.h): no worker outlives the
// ncosim process that started it (kill -9, the second SIGINT), the folder's lock is free once it
// has ended, and two campaigns of a network scenario in two threads of one process give what each
// gives alone. Built only with ns-3 (NCOSIM_NS3).
#include "network/worker.h"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "cli/spawn_ncosim.h"
#include "sim/files/output_set.h"
#include "sim/run/campaign.h"
#include "test_util.h"

namespace {

namespace fs = std::filesystem;
const fs::path kSource = NCOSIM_SOURCE_DIR;

// Every process's parent, from /proc/PID/stat ("PID (comm) STATE PPID ..."; comm may hold spaces
// and parentheses: the fields after the last ')').
std::map<pid_t, pid_t> parents() {
  std::map<pid_t, pid_t> out;
  for (const auto& e : fs::directory_iterator("/proc")) {
    const std::string name = e.path().filename().string();
    if (name.find_first_not_of("0123456789") != std::string::npos) continue;
    std::ifstream in(e.path() / "stat");
    std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const auto close = text.rfind(')');
    if (close == std::string::npos) continue;
    std::istringstream rest(text.substr(close + 1));
    char state = 0;
    pid_t ppid = 0;
    rest >> state >> ppid;
    out[static_cast<pid_t>(std::stol(name))] = ppid;
  }
  return out;
}

std::vector<pid_t> descendants(pid_t root) {
  const auto ppid = parents();
  std::vector<pid_t> out{root};
  for (std::size_t i = 0; i < out.size(); ++i) {
    for (const auto& [p, parent] : ppid) {
      if (parent == out[i]) out.push_back(p);
    }
  }
  out.erase(out.begin());
  return out;
}

// Ended: no such process, or a zombie waiting for its (new) parent to reap it.
bool ended(pid_t p) {
  std::ifstream in(fmt::format("/proc/{}/stat", p));
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const auto close = text.rfind(')');
  return !in || close == std::string::npos || text.substr(close + 2, 1) == "Z" ||
         text.substr(close + 2, 1) == "X";
}

class Workers : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           fmt::format("ncosim_workers_{}_{}", ::getpid(),
                       ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  // A long campaign of the 802.15.4 star on two threads, started in the background, once its
  // network workers run (a fork server and its run's child per thread): its pid and theirs. Its
  // runs are long (100,000 periods, over a minute each): a worker that only notices its parent's
  // end when its run ends (as the forked workers before issue 39 did) outlives the 10 s below.
  std::pair<pid_t, std::vector<pid_t>> start_campaign() {
    const pid_t pid = ncosim::testing::spawn_ncosim(
        {"run", (kSource / "scenarios/wsn_star.toml").string(), "--out", (dir_ / "wsn").string(),
         "--runs", "4", "--periods", "100000", "--threads", "2", "--no-timing", "--quiet"},
        (dir_ / "log.txt").string());
    std::vector<pid_t> workers;
    for (int i = 0; i < 600 && workers.size() < 4; ++i) {
      ::usleep(50'000);
      workers = descendants(pid);
    }
    return {pid, workers};
  }
  // The workers that have not ended within 10 s.
  static std::vector<pid_t> survivors(const std::vector<pid_t>& workers) {
    std::vector<pid_t> alive = workers;
    for (int i = 0; i < 200 && !alive.empty(); ++i) {
      std::erase_if(alive, ended);
      if (!alive.empty()) ::usleep(50'000);
    }
    for (const pid_t p : alive) ::kill(p, SIGKILL);  // never left behind by the test
    return alive;
  }
  // The output folder's lock is free: no process holds it any more.
  void expect_lock_free() {
    EXPECT_NO_THROW(ncosim::sim::OutputFolderLock((dir_ / "wsn").string()));
  }

  fs::path dir_;
};

std::string pids(const std::vector<pid_t>& v) {
  std::string s;
  for (const pid_t p : v) s += fmt::format("{} ", p);
  return s;
}

TEST_F(Workers, EndWithTheirParentAfterKill9) {
  const auto [pid, workers] = start_campaign();
  ASSERT_GE(workers.size(), 2u) << "no network workers started";
  ::kill(pid, SIGKILL);
  int status = 0;
  ASSERT_EQ(::waitpid(pid, &status, 0), pid);
  const auto left = survivors(workers);
  EXPECT_TRUE(left.empty()) << "workers still running after kill -9 of ncosim: " << pids(left);
  expect_lock_free();
}

TEST_F(Workers, EndWithTheirParentAfterTheSecondSigint) {
  const auto [pid, workers] = start_campaign();
  ASSERT_GE(workers.size(), 2u) << "no network workers started";
  ::kill(pid, SIGINT);  // stop: no new run, the runs in progress finish
  ::usleep(100'000);
  ::kill(pid, SIGINT);  // the second: ncosim ends at once
  int status = 0;
  ASSERT_EQ(::waitpid(pid, &status, 0), pid);
  EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGINT) << status;
  const auto left = survivors(workers);
  EXPECT_TRUE(left.empty()) << "workers still running after the second SIGINT: " << pids(left);
  expect_lock_free();
}

// Two campaigns of the star in two threads of this process at once: each gives exactly what it
// gives alone (its runs, links and error curve), with its own workers.
TEST(WorkersInThreads, TwoCampaignsAtOnceGiveWhatEachGivesAlone) {
  ncosim::network::set_worker_executable(NCOSIM_BINARY);
  auto load = [](std::uint64_t seed) {
    return ncosim::testing::load_one((kSource / "scenarios/wsn_star.toml").string(),
                                     {"run.runs=3", "run.periods=300", "run.error_curve=true",
                                      fmt::format("run.seed={}", seed)});
  };
  const auto a = load(1), b = load(2);
  ncosim::sim::CampaignOptions opt;
  opt.threads = 2;
  opt.time_estimators = false;
  const auto alone_a = ncosim::sim::run_campaign(*a, opt);
  const auto alone_b = ncosim::sim::run_campaign(*b, opt);
  ncosim::sim::CampaignResult both_a, both_b;
  std::thread ta([&] { both_a = ncosim::sim::run_campaign(*a, opt); });
  std::thread tb([&] { both_b = ncosim::sim::run_campaign(*b, opt); });
  ta.join();
  tb.join();
  auto same = [](const ncosim::sim::CampaignResult& x, const ncosim::sim::CampaignResult& y) {
    ASSERT_EQ(x.runs.size(), y.runs.size());
    for (std::size_t r = 0; r < x.runs.size(); ++r) {
      for (std::size_t e = 0; e < x.runs[r].size(); ++e) {
        EXPECT_EQ(x.runs[r][e].sse, y.runs[r][e].sse) << "run " << r << ", estimator " << e;
        EXPECT_EQ(x.runs[r][e].status, "ok");
      }
      ASSERT_EQ(x.link_runs[r].size(), y.link_runs[r].size());
      for (std::size_t f = 0; f < x.link_runs[r].size(); ++f) {
        const auto& sx = x.link_runs[r][f].stack;
        const auto& sy = y.link_runs[r][f].stack;
        ASSERT_TRUE(sx && sy);
        EXPECT_EQ(sx->attempts, sy->attempts);
        EXPECT_EQ(x.link_runs[r][f].delivered, y.link_runs[r][f].delivered);
      }
    }
    for (std::int64_t k = 0; k < x.curve.periods(); k += 37)
      EXPECT_EQ(x.curve.mean(k, 0), y.curve.mean(k, 0)) << "period " << k;
  };
  same(alone_a, both_a);
  same(alone_b, both_b);
  EXPECT_NE(alone_a.runs[0][0].sse, alone_b.runs[0][0].sse);  // two different campaigns
}

TEST(WorkerMain, RefusesToStartWithoutItsSocket) {
  const auto o = ncosim::testing::run_shell(std::string(NCOSIM_BINARY) + " network-worker 3<&-");
  EXPECT_EQ(o.code, 2) << o.output;
  EXPECT_NE(o.output.find("started without its socket"), std::string::npos) << o.output;
}

}  // namespace
