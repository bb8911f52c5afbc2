// tests/sumo/record_link_sumo_test.cc — `ncosim record-link` on a mobility-driven link: the
// recorded fates of a `sumo_distance` link are the campaign's (its counter-based draws at the
// positions of each run's realisation), so a `trace` link with `segment` replaying the record
// gives kalman_extended the campaign's errors run by run (what scripts/channel_study.sh relies on).
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "sumo/sumo_fixture.h"
#include "test_util.h"

namespace {

namespace fs = std::filesystem;

// Two vehicles drifting apart on a 5 km road (the slower one behind), 2 realisations.
std::string scenario_text() {
  return ncosim::testing::sumo_scenario(900, 4, 2, "follower", "cheng2007", R"([[estimator]]
kind = "kalman_extended"
max_delay = 1
)");
}

class RecordLinkSumo : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("ncosim_record_sumo_" + std::to_string(::getpid()));
    ok_ = ncosim::testing::write_sumo_road(dir_, 5000, ncosim::testing::kLeaderAndFollower);
    std::ofstream(dir_ / "s.toml") << scenario_text();
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  int ncosim(const std::string& args) {
    const std::string cmd =
        "cd '" + dir_.string() + "' && '" + NCOSIM_BINARY + "' " + args + " >out.txt 2>&1";
    const int status = std::system(cmd.c_str());
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  }
  std::string text(const std::string& name) {
    return ncosim::testing::read_text((dir_ / name).string());
  }
  std::vector<std::string> lines(const std::string& name) {
    std::vector<std::string> out;
    std::istringstream in(text(name));
    for (std::string l; std::getline(in, l);) out.push_back(l);
    return out;
  }
  fs::path dir_;
  bool ok_ = false;
};

TEST_F(RecordLinkSumo, ASegmentedReplayOfTheRecordGivesTheCampaignsErrors) {
  ASSERT_TRUE(ok_) << "netconvert failed";
  ASSERT_EQ(ncosim("run s.toml --out live --quiet --no-timing"), 0) << text("out.txt");
  ASSERT_EQ(ncosim("record-link s.toml --link v2v --out rec --quiet"), 0) << text("out.txt");
  const auto index = lines("rec/record.csv");
  ASSERT_EQ(index.size(), 2u);
  const auto links = lines("live/links.csv");
  ASSERT_EQ(links.size(), 2u);
  // record.csv: link,file,runs,periods,segment,packets,delivered,...; links.csv: ...,packets_sent,
  // packets_delivered,... (7th and 6th fields).
  auto field = [](const std::string& line, int i) {
    std::istringstream in(line);
    std::string f;
    for (int k = 0; k <= i; ++k) std::getline(in, f, ',');
    return f;
  };
  EXPECT_EQ(field(index[1], 5), "3600");
  EXPECT_EQ(field(index[1], 6), field(links[1], 5)) << index[1] << "\n" << links[1];
  // The record has losses and deliveries (the vehicles drift out of range).
  const int delivered = std::stoi(field(index[1], 6));
  EXPECT_GT(delivered, 100);
  EXPECT_LT(delivered, 3500);
  std::string replay = scenario_text();
  const std::string from =
      "kind = \"sumo_distance\"\nsender = \"leader\"\nreceiver = \"follower\"\npreset = "
      "\"cheng2007\"\n";
  ASSERT_NE(replay.find(from), std::string::npos);
  replay.replace(replay.find(from), from.size(),
                 "kind = \"trace\"\nfile = \"rec/v2v.csv\"\nsegment = 900\n");
  std::ofstream(dir_ / "replay.toml") << replay;
  ASSERT_EQ(ncosim("run replay.toml --out replayed --quiet --no-timing"), 0) << text("out.txt");
  const auto a = lines("live/runs.csv"), b = lines("replayed/runs.csv");
  ASSERT_EQ(a.size(), 5u);
  ASSERT_EQ(b.size(), 5u);
  for (std::size_t i = 1; i < a.size(); ++i) {
    EXPECT_EQ(a[i].substr(0, a[i].find(",ok,")), b[i].substr(0, b[i].find(",ok,")))
        << "run " << i - 1;
  }
}

}  // namespace
