// tests/sumo/traffic_key_test.cc — SUMO recordings are keyed by the traffic, not by the vehicles
// a case reads: a sweep over receivers records each realisation once (one SUMO run per seed) and
// every other case reuses it; a later scenario naming a vehicle the recording lacks records again.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <regex>
#include <string>

#include "sumo/sumo_fixture.h"
#include "test_util.h"

namespace {

namespace fs = std::filesystem;

struct Road3 {
  fs::path dir;
  bool ok = false;
  Road3() {
    dir = fs::temp_directory_path() / ("ncosim_sumo_traffic_" + std::to_string(::getpid()));
    ok = ncosim::testing::write_sumo_road(
        dir, 3000,
        R"(  <vehicle id="leader" type="fast" route="r" depart="0" departPos="200" departSpeed="max"/>
  <vehicle id="near" type="fast" route="r" depart="0" departPos="100" departSpeed="max"/>
  <vehicle id="far" type="slow" route="r" depart="0" departPos="0" departSpeed="max"/>
  <vehicle id="other" type="slow" route="r" depart="0" departPos="50" departSpeed="max"/>
)");
  }
  ~Road3() { fs::remove_all(dir); }
  std::string scenario(const std::string& receivers) const {
    return ncosim::testing::sumo_scenario(300, 3, 3, "near", "ns3_vanet", R"([[estimator]]
kind = "open_loop"
max_delay = 1

[[sweep]]
key = "link[0].receiver"
values = )" + receivers + R"(

[[sweep]]
key = "link[0].preset"
values = ["veins_nakagami3", "ns3_vanet"]
)");
  }
};

int count(const std::string& text, const std::string& needle) {
  int n = 0;
  for (std::size_t at = text.find(needle); at != std::string::npos; at = text.find(needle, at + 1))
    ++n;
  return n;
}

TEST(SumoTrafficKey, ReceiverSweepRecordsEachRealisationOnce) {
  const Road3 road;
  ASSERT_TRUE(road.ok) << "netconvert failed";
  std::ofstream(road.dir / "s.toml") << road.scenario(R"(["near", "far"])");
  const auto o = ncosim::testing::run_shell("cd '" + road.dir.string() + "' && '" + NCOSIM_BINARY +
                                            "' run s.toml --out r1 --quiet");
  ASSERT_EQ(o.code, 0) << o.output;
  // 2 receivers x 2 presets = 4 cases: the first records the 3 realisations (leader, near and
  // far in each), the other three reuse them.
  EXPECT_EQ(count(o.output, "sumo: 3 realisation(s) recorded, 0 reused"), 1) << o.output;
  EXPECT_EQ(count(o.output, "sumo: 0 realisation(s) recorded, 3 reused"), 3) << o.output;
  EXPECT_EQ(std::distance(fs::directory_iterator(road.dir / "cache"), fs::directory_iterator{}), 3);
  // A scenario that also needs "other": the recordings lack it, so they are replaced once (with
  // every vehicle), then reused.
  std::ofstream(road.dir / "s2.toml") << road.scenario(R"(["far", "other"])");
  const auto o2 = ncosim::testing::run_shell("cd '" + road.dir.string() + "' && '" + NCOSIM_BINARY +
                                             "' run s2.toml --out r2 --quiet");
  ASSERT_EQ(o2.code, 0) << o2.output;
  // Its base receiver ("near", written outside [[sweep]]) is not a swept value, so the base
  // scenario is also built once to validate it: it reuses the old recordings (they hold "near").
  EXPECT_EQ(count(o2.output, "sumo: 3 realisation(s) recorded, 0 reused"), 1) << o2.output;
  EXPECT_EQ(count(o2.output, "sumo: 0 realisation(s) recorded, 3 reused"), 4) << o2.output;
  EXPECT_EQ(std::distance(fs::directory_iterator(road.dir / "cache"), fs::directory_iterator{}), 3);
  // The same receiver gives the same results whichever scenario recorded its realisations.
  const std::string a = ncosim::testing::read_text((road.dir / "r1" / "links.csv").string());
  const std::string b = ncosim::testing::read_text((road.dir / "r2" / "links.csv").string());
  auto far_rows = [](const std::string& csv) {
    std::string out;
    std::istringstream in(csv);
    for (std::string l; std::getline(in, l);) {
      if (l.rfind("far,", 0) == 0) out += l + "\n";
    }
    return out;
  };
  EXPECT_FALSE(far_rows(a).empty());
  EXPECT_EQ(far_rows(a), far_rows(b));
}

}  // namespace
