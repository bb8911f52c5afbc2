// tests/network/overload_network_test.cc — overload told on a real network (results/README.md,
// "Overload and growth"): the shipped 802.15.4 star with three sensors reporting every 4 ms
// saturates its channel (the example), and every link must be told `overloaded` (links.csv,
// the note under the table, `--fail-on-status` exit 3); the shipped star as it is (four sensors
// every 20 ms) must not. Detection and false-alarm counts over fixed seeds, with 1, 2 and 5 runs.
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "test_util.h"

namespace {

namespace fs = std::filesystem;
using ncosim::testing::read_text;
using ncosim::testing::source_path;

// The shipped star without its fourth node and sensor, every sensor sending every 4 ms.
std::string overloaded_star() {
  std::string s = read_text(source_path("scenarios/wsn_star.toml"));
  const auto cut = [&](const std::string& from, const std::string& to) {
    const auto i = s.find(from);
    const auto j = s.find(to, i);
    EXPECT_TRUE(i != std::string::npos && j != std::string::npos) << from;
    s.erase(i, j - i);
  };
  cut("[[link]]\nname = \"n4\"", "[[sensor]]");
  cut("[[sensor]]\nname = \"speed 2\"", "[[estimator]]");
  const auto p = s.find("period = 0.02");
  EXPECT_NE(p, std::string::npos);
  s.replace(p, 13, "period = 0.004");
  return s;
}

class OverloadNetwork : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / fmt::format("ncosim_overload_net_{}", ::getpid());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    std::ofstream(dir_ / "overloaded.toml") << overloaded_star();
  }
  void TearDown() override { fs::remove_all(dir_); }

  // links.csv's `overload` column of a run of `scenario` (exit code in `code`).
  std::vector<std::string> verdicts(const std::string& scenario, int runs, int periods, int seed,
                                    int* code = nullptr, std::string* output = nullptr) {
    const fs::path out = dir_ / fmt::format("o{}_{}", runs, seed);
    const auto o = ncosim::testing::run_ncosim({"run", scenario, "--out", out.string(), "--quiet",
                                                "--no-timing", "--runs", std::to_string(runs),
                                                "--periods", std::to_string(periods), "--seed",
                                                std::to_string(seed), "--fail-on-status"});
    if (code != nullptr) *code = o.code;
    if (output != nullptr) *output = o.output;
    std::istringstream in(read_text((out / "links.csv").string()));
    std::string line;
    std::getline(in, line);
    std::vector<std::string> header, values;
    std::istringstream h(line);
    for (std::string c; std::getline(h, c, ',');) header.push_back(c);
    const auto at = static_cast<std::size_t>(std::find(header.begin(), header.end(), "overload") -
                                             header.begin());
    while (std::getline(in, line)) {
      std::vector<std::string> cells;
      std::istringstream r(line);
      for (std::string c; std::getline(r, c, ',');) cells.push_back(c);
      values.push_back(at < cells.size() ? cells[at] : "?");
    }
    return values;
  }
  fs::path dir_;
};

TEST_F(OverloadNetwork, TheSaturatedStarIsToldOverloadedWithOneTwoOrFiveRuns) {
  const std::string scenario = (dir_ / "overloaded.toml").string();
  constexpr int kSeeds = 4;
  for (const int runs : {1, 2, 5}) {
    int told = 0, tested = 0;
    for (int seed = 1; seed <= kSeeds; ++seed) {
      int code = 0;
      std::string output;
      const auto v = verdicts(scenario, runs, 1000, seed, &code, &output);
      ASSERT_EQ(v.size(), 3U);
      tested += 3;
      told += static_cast<int>(std::count(v.begin(), v.end(), "overloaded"));
      if (std::count(v.begin(), v.end(), "overloaded") == 0) continue;
      EXPECT_EQ(code, 3) << output;  // --fail-on-status
      EXPECT_NE(output.find("overloaded link(s)"), std::string::npos) << output;
      EXPECT_NE(output.find("**overloaded**: offered 1 packet(s)/period"), std::string::npos)
          << output;
    }
    std::cout << fmt::format("overloaded star, {} run(s): {} of {} links told overloaded\n", runs,
                             told, tested);
    EXPECT_EQ(told, tested) << runs << " run(s)";
  }
}

TEST_F(OverloadNetwork, TheShippedStarIsNot) {
  const std::string scenario = source_path("scenarios/wsn_star.toml");
  int told = 0, tested = 0;
  for (int seed = 1; seed <= 3; ++seed) {
    int code = 0;
    std::string output;
    const auto v = verdicts(scenario, 5, 600, seed, &code, &output);
    ASSERT_EQ(v.size(), 4U);
    EXPECT_EQ(code, 0) << output;
    tested += 4;
    for (const auto& x : v) told += x != "none";
  }
  std::cout << fmt::format("shipped star, 5 runs: {} of {} links told\n", told, tested);
  EXPECT_EQ(told, 0);
}

}  // namespace
