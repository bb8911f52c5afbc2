// tests/network/network_sumo_test.cc — network nodes that ride SUMO vehicles (a [[link]] of kind
// network with `vehicle`, a [[network]] with `sink_vehicle`): the nodes move with the vehicles
// period by period, a vehicle not in the traffic sends nothing and hears nothing, and the keys are
// refused where they cannot apply. Built with ns-3 and SUMO.
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "sumo/sumo_fixture.h"
#include "test_util.h"

namespace {

namespace fs = std::filesystem;
using Outcome = ncosim::testing::CommandOutcome;
Outcome ncosim(const std::vector<std::string>& args) { return ncosim::testing::run_ncosim(args); }

// A 3 km road: "leader" departs at `leader_depart` s, 100 m from the road's start, at up to
// 30 m/s; "follower" departs at 0 s from the start at up to 15 m/s.
std::string vehicles(int leader_depart) {
  return fmt::format(
      R"(  <vehicle id="follower" type="slow" route="r" depart="0" departPos="0" departSpeed="max"/>
  <vehicle id="leader" type="fast" route="r" depart="{}" departPos="100" departSpeed="max"/>
)",
      leader_depart);
}

// The leader's samples go over an 802.15.4 node riding it; the sink rides the follower (or sits
// at `sink`). Free-space path loss (exponent 2): in range up to about 900 m at 0 dBm.
std::string scenario(int periods, const std::string& sink, const std::string& sender) {
  return fmt::format(R"([run]
periods = {}
warmup = 0
runs = 1
period = 0.1

[sumo]
net = "net.net.xml"
routes = "r.rou.xml"
step = 0.1
cache = "cache"

[plant]
kind = "sumo_vehicle"
vehicle = "leader"
model = "constant_velocity"
q = 1.0

[[network]]
name = "wsn"
kind = "lr_wpan"
path_loss_exponent = 2.0
{}

[[link]]
name = "v2v"
kind = "network"
network = "wsn"
bytes = 24
{}

[[sensor]]
C = [[1.0, 0.0], [0.0, 1.0]]
R = [[1.0, 0.0], [0.0, 0.01]]
link = "v2v"

[[estimator]]
name = "kf"
kind = "kalman_extended"
max_delay = 2
)",
                     periods, sink, sender);
}

class NetworkSumo : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           fmt::format("ncosim_network_sumo_{}_{}", ::getpid(),
                       ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    if (!NCOSIM_HAVE_SUMO) GTEST_SKIP() << "built without SUMO";
    if (!ncosim::testing::write_sumo_road(dir_, 3000, vehicles(5)))
      GTEST_SKIP() << "netconvert failed";
  }
  void TearDown() override { fs::remove_all(dir_); }
  // links.csv's packets_sent and packets_delivered of the one link.
  std::pair<long, long> sent_and_delivered(const std::string& text) {
    std::ofstream(dir_ / "s.toml") << text;
    const Outcome o = ncosim({"run", (dir_ / "s.toml").string(), "--out", (dir_ / "out").string(),
                              "--quiet", "--replace"});
    EXPECT_EQ(o.code, 0) << o.output;
    std::ifstream in(dir_ / "out" / "links.csv");
    std::string header, row;
    std::getline(in, header);
    std::getline(in, row);
    const auto cell = [](const std::string& line, int i) {
      std::istringstream s(line);
      std::string c;
      for (int j = 0; j <= i; ++j) std::getline(s, c, ',');
      return c;
    };
    int sent = -1, delivered = -1;
    for (int i = 0; i < 30; ++i) {
      if (cell(header, i) == "packets_sent") sent = i;
      if (cell(header, i) == "packets_delivered") delivered = i;
    }
    return {std::stol(cell(row, sent)), std::stol(cell(row, delivered))};
  }
  fs::path dir_;
};

// The leader departs at 5 s: its node sends nothing before (50 or 51 periods, as SUMO inserts it
// at 5.0 s), then every sample reaches the follower's node, at most a few hundred metres behind.
// links.csv counts a packet once its fate is known: the last period's sample is still in the air
// when the run ends (a network's delay is at least one period), so 149 of 150.
TEST_F(NetworkSumo, ANodeRidingAVehicleSendsOnlyWhileTheVehicleIsInTheTraffic) {
  const auto [sent, delivered] =
      sent_and_delivered(scenario(150, "sink_vehicle = \"follower\"", "vehicle = \"leader\""));
  EXPECT_EQ(sent, 149);
  EXPECT_GE(delivered, 98);
  EXPECT_LE(delivered, 99);
}

// The same, the sink 5 km away from the road: out of range, nothing is delivered; the sink at the
// road's start: the leader drives out of range (about 900 m) and its late samples are lost.
TEST_F(NetworkSumo, TheSinkRidesItsVehicle) {
  EXPECT_EQ(sent_and_delivered(
                scenario(150, "sink_position = [0.0, 5000.0, 0.0]", "vehicle = \"leader\""))
                .second,
            0);
  const auto [sent, delivered] =
      sent_and_delivered(scenario(600, "sink_position = [0.0, 0.0, 1.5]", "vehicle = \"leader\""));
  EXPECT_EQ(sent, 599);
  EXPECT_GT(delivered, 100);  // the first seconds after the departure (100 m and on)
  EXPECT_LT(delivered, 550);  // 60 s at up to 30 m/s: well beyond 900 m at the end
  const auto [sent2, delivered2] =
      sent_and_delivered(scenario(600, "sink_vehicle = \"follower\"", "vehicle = \"leader\""));
  EXPECT_EQ(sent2, 599);
  EXPECT_GT(delivered2, delivered);  // the follower follows: the distance grows more slowly
}

// [[background]] vehicles = "all": a node on every vehicle of the traffic but those already a
// link's node or the sink (the leader and the follower here), so a third vehicle beside them,
// saturating the channel, costs the leader's samples; without it nothing changes.
TEST_F(NetworkSumo, EveryVehicleBeaconsButTheLinksAndTheSinksOwn) {
  const std::string base = scenario(150, "sink_vehicle = \"follower\"", "vehicle = \"leader\"");
  const std::string every =
      "\n[[background]]\nnetwork = \"wsn\"\nvehicles = \"all\"\nrate = \"saturated\"\n";
  const auto alone = sent_and_delivered(base);
  EXPECT_EQ(sent_and_delivered(base + every), alone);  // only the leader and the follower
  ASSERT_TRUE(ncosim::testing::write_sumo_road(
      dir_, 3000,
      vehicles(5) +
          R"(  <vehicle id="other" type="fast" route="r" depart="5" departPos="110" departSpeed="max"/>
)"));
  const auto crowded = sent_and_delivered(base + every);
  EXPECT_EQ(crowded.first, alone.first);
  EXPECT_LT(crowded.second, alone.second);
}

TEST_F(NetworkSumo, BadInputNamesTheKey) {
  const struct {
    std::string sink, sender, message;
  } cases[] = {
      {"sink_vehicle = \"follower\"", "vehicle = \"leader\"\nposition = [0.0, 0.0, 0.0]",
       "key 'link[0].vehicle': expected `vehicle` or `position`, not both"},
      {"sink_vehicle = \"follower\"\nsink_position = [0.0, 0.0, 0.0]", "vehicle = \"leader\"",
       "key 'network[0].sink_vehicle': expected `sink_vehicle` or `sink_position`, not both"},
      {"sink_vehicle = \"nobody\"", "vehicle = \"leader\"", "key 'network[0].sink_vehicle'"},
  };
  for (const auto& c : cases) {
    std::ofstream(dir_ / "bad.toml") << scenario(100, c.sink, c.sender);
    const Outcome o = ncosim({"check", (dir_ / "bad.toml").string()});
    EXPECT_EQ(o.code, 2) << o.output;
    EXPECT_NE(o.output.find(c.message), std::string::npos) << c.message << "\n" << o.output;
  }
  // Not on a network without positions, nor without [sumo].
  std::string csma = scenario(100, "", "vehicle = \"leader\"");
  csma.replace(csma.find("kind = \"lr_wpan\"\npath_loss_exponent = 2.0"),
               std::string("kind = \"lr_wpan\"\npath_loss_exponent = 2.0").size(),
               "kind = \"csma\"");
  std::ofstream(dir_ / "bad.toml") << csma;
  Outcome o = ncosim({"check", (dir_ / "bad.toml").string()});
  EXPECT_EQ(o.code, 2);
  EXPECT_NE(o.output.find("key 'link[0].vehicle': expected no vehicle: network \"wsn\" (kind csma) "
                          "has no positions"),
            std::string::npos)
      << o.output;
}

}  // namespace
