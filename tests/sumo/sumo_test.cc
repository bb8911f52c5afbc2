// tests/sumo/sumo_test.cc — the SUMO component: channel presets against independent formulas,
// delivery per distance bin against p(d) on a scripted two-vehicle road, replay == live,
// reuse of recordings, clean stdout and exit 2 on SUMO errors. The SUMO inputs are generated
// here (plain XML + netconvert), in a temporary folder.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <boost/math/distributions/gamma.hpp>
#include <boost/math/distributions/normal.hpp>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <numbers>
#include <random>
#include <sstream>

#include "sim/run/campaign.h"
#include "sumo/channel.h"
#include "sumo/sumo_fixture.h"
#include "sumo/traffic.h"
#include "test_util.h"

namespace ncosim::sumo {
namespace {

namespace fs = std::filesystem;

// ---------------------------------------------------------------- channel formulas

double killat(double d, double range) {  // Killat & Hartenstein 2009, m = 3, free space
  const double x = (d / range) * (d / range);
  return std::exp(-3.0 * x) * (1.0 + 3.0 * x + 4.5 * x * x);
}

TEST(Channel, VeinsPresetIsKillatHartensteinClosedForm) {
  const Channel ch = make_preset("veins_nakagami3");
  // Range R: the distance at which the mean free-space power equals the threshold.
  const double lambda = kSpeedOfLight / 5.89e9;
  const double pt_dbm = 10.0 * std::log10(20.0);
  const double range =
      lambda / (4.0 * std::numbers::pi) * std::pow(10.0, (pt_dbm - (-89.0)) / 20.0);
  EXPECT_NEAR(range, 510.5, 0.1);  // by hand: 0.0509 m / 4 pi x 10^(102.01 / 20)
  for (double d = 1.5; d < 1500.0; d += 7.3) {
    EXPECT_NEAR(ch.reception_probability(d), killat(d, range), 1e-9) << d;
  }
}

double gamma_tail(double m, double mean_mw, double threshold_mw) {
  boost::math::gamma_distribution<double> g(m, mean_mw / m);
  return boost::math::cdf(boost::math::complement(g, threshold_mw));
}

TEST(Channel, Ns3PresetIsThreeLogDistanceWithNakagami) {
  const Channel ch = make_preset("ns3_vanet");
  for (double d = 1.5; d < 1500.0; d += 3.1) {
    double loss = 46.6777;
    if (d <= 200.0) {
      loss += 19.0 * std::log10(d);
    } else if (d <= 500.0) {
      loss += 19.0 * std::log10(200.0) + 38.0 * std::log10(d / 200.0);
    } else {
      loss += 19.0 * std::log10(200.0) + 38.0 * std::log10(500.0 / 200.0) +
              38.0 * std::log10(d / 500.0);
    }
    const double mean_mw = std::pow(10.0, (20.0 - loss) / 10.0);
    const double m = d < 80.0 ? 1.5 : 0.75;
    EXPECT_NEAR(ch.reception_probability(d), gamma_tail(m, mean_mw, std::pow(10.0, -96.0 / 10.0)),
                1e-9)
        << d;
  }
}

TEST(Channel, ChengPresetIsDualSlopeWithBinnedNakagami) {
  const Channel ch = make_preset("cheng2007");
  // Artery's VanetNakagamiFading defaults (riebl/artery src/artery/inet/VanetNakagamiFading.ned):
  // free space at 1 m, gamma1 = 2 up to 100 m, gamma2 = 4 beyond, shapes per distance bin.
  const double pl0 = 20.0 * std::log10(4.0 * std::numbers::pi * 5.9e9 / kSpeedOfLight);
  const double edges[] = {4.7, 11.7, 28.9, 71.6, 177.3};
  const double ms[] = {3.01, 1.18, 1.94, 1.86, 0.45, 0.32};
  for (double d = 1.2; d < 1200.0; d += 1.7) {
    const double loss =
        d <= 100.0 ? pl0 + 20.0 * std::log10(d) : pl0 + 40.0 + 40.0 * std::log10(d / 100.0);
    int bin = 0;
    while (bin < 5 && d >= edges[bin]) ++bin;
    const double mean_mw = std::pow(10.0, (20.0 - loss) / 10.0);
    EXPECT_NEAR(ch.reception_probability(d), gamma_tail(ms[bin], mean_mw, std::pow(10.0, -8.9)),
                1e-9)
        << d;
  }
}

TEST(Channel, IntegerAndRealNakagamiAgreeAndLognormalIsTheNormalTail) {
  for (double z : {0.01, 0.3, 1.0, 2.5, 7.0}) {
    for (int m = 1; m <= 6; ++m) {
      EXPECT_NEAR(nakagami_exceedance(m, z), boost::math::gamma_q(static_cast<double>(m), m * z),
                  1e-12);
    }
  }
  Channel ch = make_preset("ns3_vanet");
  ch.fading.kind = Fading::Kind::kLognormal;
  ch.fading.sigma_db = 4.0;
  boost::math::normal_distribution<double> n(0.0, 4.0);
  for (double d = 10.0; d < 1500.0; d += 37.0) {
    const double margin = ch.threshold_dbm - ch.mean_rx_dbm(d);
    EXPECT_NEAR(ch.reception_probability(d), boost::math::cdf(boost::math::complement(n, margin)),
                1e-9);
  }
}

TEST(Channel, DelayLaws) {
  DelayLaw p;  // 300 bytes at 6 Mbit/s: ceil((16 + 2400 + 6) / 48) = 51 symbols
  EXPECT_NEAR(p.frame_time(), 40e-6 + 51 * 8e-6, 1e-15);
  EXPECT_NEAR(p.sample(0.7), 32e-6 + 6 * 13e-6 + 448e-6, 1e-15);
  p.backoff = true;
  EXPECT_NEAR(p.sample(0.999), 558e-6 + 15 * 13e-6, 1e-12);
  EXPECT_NEAR(p.cdf(558e-6 + 3 * 13e-6 + 1e-9), 4.0 / 16.0, 1e-12);
  DelayLaw c;
  c.kind = DelayLaw::Kind::kCv2xMode4;
  EXPECT_NEAR(c.sample(0.5), 0.0505, 1e-15);
  Channel ch = make_preset("veins_nakagami3");
  ch.delay = c;
  double sum = 0.0;
  for (int j = 0; j < 10; ++j) sum += ch.delay_period_probability(100.0, 0.02, j);
  EXPECT_NEAR(sum, 1.0, 1e-12);
  EXPECT_NEAR(ch.delay_period_probability(100.0, 0.02, 0),
              (0.02 - 1e-3 - 100.0 / kSpeedOfLight) / 0.099, 1e-9);
}

TEST(Channel, DeclaredDelayDefaultsAreDelayLawsInitialisers) {
  // read_channel takes the delay law's defaults from channel_keys(); DelayLaw's own initialisers
  // (used by the presets) must say the same.
  const DelayLaw d;
  const config::Keys& k = channel_keys();
  EXPECT_EQ(d.rate, std::get<double>(k.at("rate").default_value()) * 1e6);
  EXPECT_EQ(d.size, std::get<std::int64_t>(k.at("size").default_value()));
  EXPECT_EQ(d.aifsn, std::get<std::int64_t>(k.at("aifsn").default_value()));
  EXPECT_EQ(d.cw, std::get<std::int64_t>(k.at("cw").default_value()));
  EXPECT_EQ(d.backoff, std::get<bool>(k.at("backoff").default_value()));
  EXPECT_EQ(d.t1, std::get<double>(k.at("t1").default_value()));
  EXPECT_EQ(d.t2, std::get<double>(k.at("t2").default_value()));
  for (const auto& name : preset_names()) {
    const DelayLaw p = make_preset(name).delay;
    EXPECT_EQ(p.rate, d.rate);
    EXPECT_EQ(p.size, d.size);
    EXPECT_EQ(p.t1, d.t1);
  }
}

TEST(Channel, KeyedDrawsAreDeterministicAndDistinct) {
  const auto k = stream_key(1, 2, name_hash("a"), name_hash("b"));
  EXPECT_EQ(keyed_uniform(k, 5, 0), keyed_uniform(k, 5, 0));
  EXPECT_NE(keyed_uniform(k, 5, 0), keyed_uniform(k, 6, 0));
  EXPECT_NE(keyed_uniform(k, 5, 0), keyed_uniform(k, 5, 1));
  EXPECT_NE(k, stream_key(1, 2, name_hash("b"), name_hash("a")));
  double mean = 0.0;
  for (int i = 0; i < 100000; ++i) mean += keyed_uniform(k, static_cast<std::uint64_t>(i), 0);
  EXPECT_NEAR(mean / 100000.0, 0.5, 4.5 * std::sqrt(1.0 / 12.0 / 100000.0));
}

// ---------------------------------------------------------------- scripted SUMO road

// A 5 km two-lane road; "leader" departs 100 m ahead at 30 m/s, "follower" at 15 m/s: their
// distance grows from 100 m to ~1000 m in 60 s.
struct Road {
  fs::path dir;
  Road() {
    dir = fs::temp_directory_path() / ("ncosim_sumo_test_" + std::to_string(::getpid()));
    ok = testing::write_sumo_road(dir, 5000, testing::kLeaderAndFollower);
    std::ofstream(dir / "s.toml") << testing::sumo_scenario(600, 6, 2, "follower", "ns3_vanet",
                                                            R"([[estimator]]
kind = "kalman_extended"
max_delay = 1

[[estimator]]
kind = "jump"
grouping = "S3"
history = 1
max_delay = 1

[[estimator]]
kind = "open_loop"
max_delay = 1
)");
  }
  ~Road() { fs::remove_all(dir); }
  std::string scenario() const { return (dir / "s.toml").string(); }
  bool ok = false;
};

const Road& road() {
  static const Road r;
  return r;
}

struct Output {
  int code;
  std::string out, err;
};

Output run_ncosim(const std::string& args, const std::string& env = "") {
  const fs::path dir = road().dir;
  const std::string cmd = "cd '" + dir.string() + "' && " + env + "'" + NCOSIM_BINARY + "' " +
                          args + " >stdout.txt 2>stderr.txt";
  const int status = std::system(cmd.c_str());
  return Output{WIFEXITED(status) ? WEXITSTATUS(status) : -1,
                testing::read_text((dir / "stdout.txt").string()),
                testing::read_text((dir / "stderr.txt").string())};
}

// summary.csv without the measured ns_per_period column (wall-clock timing).
std::string summary_without_timing(const std::string& folder) {
  std::ifstream in(road().dir / folder / "summary.csv");
  std::string out, line;
  int timing = -1;
  while (std::getline(in, line)) {
    std::vector<std::string> cells;
    std::stringstream ss(line);
    for (std::string c; std::getline(ss, c, ',');) cells.push_back(c);
    if (timing < 0) {
      for (std::size_t i = 0; i < cells.size(); ++i) {
        if (cells[i] == "ns_per_period") timing = static_cast<int>(i);
      }
    }
    for (std::size_t i = 0; i < cells.size(); ++i) {
      if (static_cast<int>(i) != timing) out += cells[i] + ",";
    }
    out += "\n";
  }
  return out;
}

TEST(SumoCampaign, RecordsOnceReusesAndLiveEqualsReplay) {
  ASSERT_TRUE(road().ok) << "netconvert failed";
  const Output first = run_ncosim("run s.toml --out r1 --quiet");
  ASSERT_EQ(first.code, 0) << first.err;
  EXPECT_NE(first.err.find("sumo: 2 realisation(s) recorded, 0 reused"), std::string::npos)
      << first.err;
  // Nothing from SUMO on stdout: it is exactly the summary table and the closing line.
  EXPECT_EQ(first.out.rfind("# s\n", 0), 0u) << first.out;
  for (const char* noise : {"Loading", "Success", "Warning", "Step #", "sumo:"}) {
    EXPECT_EQ(first.out.find(noise), std::string::npos) << noise << " in stdout:\n" << first.out;
  }
  // The second campaign cannot start SUMO: the `sumo` binary and the libsumo module are
  // pointed at nothing.
  const Output second = run_ncosim(
      "run s.toml --out r2 --quiet",
      "NCOSIM_SUMO_BINARY=/nonexistent/sumo NCOSIM_SUMO_MODULE=/nonexistent/libsumo.so ");
  ASSERT_EQ(second.code, 0) << second.err;
  EXPECT_NE(second.err.find("sumo: 0 realisation(s) recorded, 2 reused"), std::string::npos)
      << second.err;
  // Live: libsumo in worker processes; the recordings exist, so the `sumo` binary is not needed.
  const Output live = run_ncosim("run s.toml --out r3 --quiet --set 'sumo.mode=\"live\"'",
                                 "NCOSIM_SUMO_BINARY=/nonexistent/sumo ");
  ASSERT_EQ(live.code, 0) << live.err;
  // The guard is real: live mode needs the module (in its worker) and fails without it (a
  // run-time failure, not bad input).
  const Output no_module = run_ncosim("run s.toml --out r4 --quiet --set 'sumo.mode=\"live\"'",
                                      "NCOSIM_SUMO_MODULE=/nonexistent/libsumo.so ");
  EXPECT_NE(no_module.code, 0);
  EXPECT_NE(no_module.err.find("cannot load the libsumo module"), std::string::npos)
      << no_module.err;
  const std::string a = summary_without_timing("r1");
  EXPECT_GT(a.size(), 100u);
  EXPECT_EQ(a, summary_without_timing("r2"));
  EXPECT_EQ(a, summary_without_timing("r3"));
  // Estimation actually uses the beacons: the filters beat open loop by orders of magnitude.
  EXPECT_NE(a.find("kalman_extended"), std::string::npos);
}

// ---------------------------------------------------------------- recording (FCD) and live workers

SumoInputs road_inputs() {
  SumoInputs in;
  in.args = {"-n", (road().dir / "net.net.xml").string(), "-r",
             (road().dir / "r.rou.xml").string()};
  in.step_ms = 100;
  return in;
}

// The processes whose parent is this one (zombies included).
std::vector<pid_t> children() {
  std::vector<pid_t> out;
  for (const auto& e : fs::directory_iterator("/proc")) {
    const std::string name = e.path().filename().string();
    if (name.find_first_not_of("0123456789") != std::string::npos) continue;
    std::ifstream stat(e.path() / "stat");
    std::string line;
    if (!std::getline(stat, line)) continue;
    const auto close = line.rfind(')');
    if (close == std::string::npos) continue;
    std::stringstream rest(line.substr(close + 2));
    char state = 0;
    pid_t ppid = 0;
    rest >> state >> ppid;
    if (ppid == ::getpid()) out.push_back(std::stoi(name));
  }
  return out;
}

bool libsumo_loaded() {
  return testing::read_text("/proc/self/maps").find("libsumocpp") != std::string::npos;
}

TEST(SumoRecording, FcdRecordingEqualsLiveLibsumoBitForBit) {
  // Recording: the `sumo` binary's FCD text; live: libsumo's doubles in a worker process. Every
  // value of every frame must be the same double (the text carries 40 decimals).
  ASSERT_TRUE(road().ok);
  set_worker_executable(NCOSIM_BINARY);
  const std::vector<std::string> vehicles{"follower", "leader", "nobody"};
  const SumoInputs in = road_inputs();
  const Recording r = record(in, 3, 600, vehicles);
  ASSERT_EQ(r.frames, 600);
  ASSERT_EQ(r.vehicles, vehicles);
  auto live = start_live(in, 3, vehicles);
  int compared = 0, tiny = 0;
  for (std::int64_t f = 0; f < r.frames; ++f) {
    live->advance(f * (kernel::kSecond / 10));
    for (int v = 0; v < 3; ++v) {
      const auto& a = r.at(f, v);
      const auto& b = live->vehicle(v);
      ASSERT_EQ(a.present, b.present) << f << " " << v;
      const double ra[] = {a.x, a.y, a.pos, a.speed, a.accel};
      const double rb[] = {b.x, b.y, b.pos, b.speed, b.accel};
      for (int k = 0; k < 5; ++k) {
        ASSERT_EQ(std::memcmp(&ra[k], &rb[k], sizeof(double)), 0)
            << "frame " << f << " vehicle " << v << " field " << k << ": " << ra[k] << " vs "
            << rb[k];
        tiny += rb[k] != 0.0 && std::abs(rb[k]) < 1e-23;
      }
      compared += a.present;
    }
  }
  EXPECT_GT(compared, 1000);
  EXPECT_EQ(tiny, 0);  // no value the 40-decimal text could not carry (see the next test)
  EXPECT_FALSE(r.at(0, 0).present);    // frame 0: before the first step
  EXPECT_TRUE(r.at(1, 0).present);     // departed at t = 0
  EXPECT_FALSE(r.at(599, 2).present);  // "nobody" never drives
  // This process never loaded libsumo: only the worker did.
  EXPECT_FALSE(libsumo_loaded());
  live.reset();
  EXPECT_TRUE(children().empty()) << "worker not reaped";
}

TEST(SumoRecording, FortyDecimalsCarryEveryDoubleDownToAbout1e23) {
  // SUMO prints with std::fixed and setprecision(40): 17 significant digits (enough for any
  // double) down to ~1e-23; smaller magnitudes lose bits.
  auto round_trips = [](double x) {
    std::ostringstream o;
    o << std::fixed << std::setprecision(40) << x;
    return std::strtod(o.str().c_str(), nullptr) == x;
  };
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> mantissa(1.0, 10.0);
  std::uniform_int_distribution<int> exponent(-23, 4);
  for (int i = 0; i < 20000; ++i) {
    const double x = mantissa(rng) * std::pow(10.0, exponent(rng));
    ASSERT_TRUE(round_trips(x)) << x;
    ASSERT_TRUE(round_trips(-x)) << -x;
  }
  int lost = 0;
  for (int i = 0; i < 1000; ++i) lost += !round_trips(mantissa(rng) * 1e-30);
  EXPECT_GT(lost, 900);
}

TEST(SumoRecording, ATeleportingVehicleIsAbsentInTheRecordingAndLiveAlike) {
  // SUMO's FCD output leaves out a vehicle while it teleports; the live worker must too (and
  // keep its last state), else live and replay differ. One-lane road a-b-c-d: a blocker stops
  // for 200 s on ab, a second one fills the 7 m edge bc; "stuck", behind the first, waits 2 s
  // (--time-to-teleport 2) and teleports for several seconds until it reaches cd.
  ASSERT_TRUE(road().ok);
  set_worker_executable(NCOSIM_BINARY);
  const fs::path dir = road().dir / "teleport";
  fs::create_directories(dir);
  std::ofstream(dir / "n.nod.xml")
      << R"(<nodes><node id="a" x="0" y="0"/><node id="b" x="1000" y="0"/>
<node id="c" x="1007" y="0"/><node id="d" x="3000" y="0"/></nodes>)";
  std::ofstream(dir / "e.edg.xml")
      << R"(<edges><edge id="ab" from="a" to="b" numLanes="1" speed="20"/>
<edge id="bc" from="b" to="c" numLanes="1" speed="20"/><edge id="cd" from="c" to="d" numLanes="1" speed="20"/></edges>)";
  std::ofstream(dir / "t.rou.xml") << R"(<routes>
  <vType id="car" maxSpeed="20" sigma="0"/>
  <route id="r" edges="ab bc cd"/>
  <route id="r2" edges="bc cd"/>
  <vehicle id="blocker" type="car" route="r" depart="0" departPos="300"><stop lane="ab_0" endPos="320" duration="200"/></vehicle>
  <vehicle id="blocker2" type="car" route="r2" depart="0" departPos="0"><stop lane="bc_0" endPos="6" duration="200"/></vehicle>
  <vehicle id="stuck" type="car" route="r" depart="0" departPos="0"/>
</routes>)";
  const std::string cmd = "cd '" + dir.string() +
                          "' && SUMO_HOME=/usr/share/sumo netconvert -n n.nod.xml -e e.edg.xml -o "
                          "net.net.xml >/dev/null 2>&1";
  ASSERT_EQ(std::system(cmd.c_str()), 0);
  SumoInputs in;
  in.args = {"-n",
             (dir / "net.net.xml").string(),
             "-r",
             (dir / "t.rou.xml").string(),
             "--time-to-teleport",
             "2"};
  in.step_ms = 100;
  const std::vector<std::string> vehicles{"stuck"};
  const Recording r = record(in, 1, 1200, vehicles);
  auto live = start_live(in, 1, vehicles);
  int absent_after_departure = 0, back_after_absence = 0;
  bool departed = false;
  for (std::int64_t f = 0; f < r.frames; ++f) {
    live->advance(f * (kernel::kSecond / 10));
    const auto& a = r.at(f, 0);
    const auto& b = live->vehicle(0);
    ASSERT_EQ(a.present, b.present) << "frame " << f;
    const double ra[] = {a.x, a.y, a.pos, a.speed, a.accel};
    const double rb[] = {b.x, b.y, b.pos, b.speed, b.accel};
    for (int k = 0; k < 5; ++k)
      ASSERT_EQ(std::memcmp(&ra[k], &rb[k], sizeof(double)), 0) << "frame " << f << " field " << k;
    back_after_absence += absent_after_departure > 0 && a.present;
    departed = departed || a.present;
    absent_after_departure += departed && !a.present;
  }
  EXPECT_TRUE(departed);
  // Absent while teleporting (27.6 s to 34.8 s measured), then present again on cd.
  EXPECT_GT(absent_after_departure, 10)
      << "the vehicle never teleported: the test does not test anything";
  EXPECT_GT(back_after_absence, 10);
  live.reset();
  EXPECT_TRUE(children().empty());
}

TEST(SumoRecording, SumoErrorsAndMissingBinaryAreClear) {
  ASSERT_TRUE(road().ok);
  SumoInputs in = road_inputs();
  in.args[1] = (road().dir / "missing.net.xml").string();
  try {
    record(in, 1, 10, {"leader"});
    ADD_FAILURE() << "no error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("missing.net.xml' is not accessible"), std::string::npos)
        << e.what();
    EXPECT_EQ(std::string(e.what()).find("Quitting"), std::string::npos) << e.what();
  }
  ::setenv("NCOSIM_SUMO_BINARY", "/nonexistent/sumo", 1);
  EXPECT_THROW(sumo_binary(), std::runtime_error);
  ::unsetenv("NCOSIM_SUMO_BINARY");
  EXPECT_TRUE(fs::exists(sumo_binary()));
}

struct FcdCase {
  std::string body, expect;
};

TEST(SumoRecording, FcdReaderIsStrict) {
  const std::string head = R"(<?xml version="1.0" encoding="UTF-8"?>
<!-- generated by sumo <configuration> ... -->
<fcd-export xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance">
)";
  const std::string a =
      R"(<vehicle id="a" x="1.5" y="2" speed="3" acceleration="-0.25" odometer="7"/>)";
  const fs::path file =
      fs::temp_directory_path() / ("ncosim_fcd_test_" + std::to_string(::getpid()) + ".xml");
  auto parse = [&](const std::string& body) {
    std::ofstream(file) << head << body;
    return parse_fcd(file.string(), 100, 5, {"a", "b"});
  };
  // Good: a at t = 0 and 0.1, absent at 0.2 (keeps its last state), SUMO stopped after 0.2.
  const Recording r =
      parse("<timestep time=\"0.000\">\n  " + a + "\n</timestep>\n<timestep time=\"0.100\">" + a +
            "</timestep>\n<timestep time=\"0.200\"/>\n</fcd-export>\n");
  EXPECT_FALSE(r.at(0, 0).present);
  EXPECT_EQ(r.at(0, 0).x, 0.0);
  EXPECT_TRUE(r.at(1, 0).present);
  EXPECT_TRUE(r.at(2, 0).present);
  EXPECT_EQ(r.at(2, 0).x, 1.5);
  EXPECT_EQ(r.at(2, 0).pos, 7.0);
  EXPECT_EQ(r.at(2, 0).accel, -0.25);
  EXPECT_FALSE(r.at(3, 0).present);
  EXPECT_EQ(r.at(3, 0).speed, 3.0);
  EXPECT_FALSE(r.at(4, 0).present);
  for (int f = 0; f < 5; ++f) EXPECT_FALSE(r.at(f, 1).present);
  const std::vector<FcdCase> bad{
      {"<timestep time=\"0.100\"/></fcd-export>", "timestep time=\"0.100\" where 0.000 s"},
      {"<timestep time=\"0.000\"/><timestep time=\"0.000\"/></fcd-export>", "where 0.100 s"},
      {"<timestep time=\"0.000\"><person id=\"p\"/></timestep></fcd-export>",
       "expected '<vehicle'"},
      {"<timestep time=\"0.000\"><vehicle id=\"c\" x=\"1\" y=\"2\" speed=\"3\" acceleration=\"0\" "
       "odometer=\"0\"/>"
       "</timestep></fcd-export>",
       "vehicle \"c\" was not asked for"},
      {"<timestep time=\"0.000\"><vehicle id=\"a\" x=\"1\" y=\"2\" speed=\"fast\" "
       "acceleration=\"0\" odometer=\"0\"/>"
       "</timestep></fcd-export>",
       "expected a finite number, got \"fast\""},
      {"<timestep time=\"0.000\"><vehicle id=\"a\" x=\"1\" y=\"2\" speed=\"3\" "
       "odometer=\"0\"/></timestep></fcd-export>",
       "expected <vehicle id x y"},
      {"<timestep time=\"0.000\">" + a + a + "</timestep></fcd-export>",
       "\"a\" twice in one timestep"},
      {"<timestep time=\"0.000\"/>", "expected '<timestep'"},
      {"<timestep time=\"0.000\"/></fcd-export>junk", "unexpected content after </fcd-export>"},
      {"<timestep time=\"0.000\" lane=\"x\"/></fcd-export>", "expected <timestep time="},
  };
  for (const auto& c : bad) {
    try {
      parse(c.body);
      ADD_FAILURE() << "accepted: " << c.body;
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find(c.expect), std::string::npos) << c.body << "\n"
                                                                         << e.what();
      EXPECT_NE(std::string(e.what()).find("byte "), std::string::npos) << e.what();
    }
  }
  fs::remove(file);
}

TEST(SumoLive, WorkerDeathIsAClearErrorAndNoZombieRemains) {
  ASSERT_TRUE(road().ok);
  set_worker_executable(NCOSIM_BINARY);
  const std::vector<std::string> vehicles{"leader"};
  auto live = start_live(road_inputs(), 1, vehicles);
  live->advance(10 * kernel::kSecond);
  EXPECT_TRUE(live->vehicle(0).present);
  const auto kids = children();
  ASSERT_EQ(kids.size(), 1u);
  ::kill(kids[0], SIGKILL);
  try {
    live->advance(20 * kernel::kSecond);
    ADD_FAILURE() << "no error after the worker died";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("SUMO live worker (seed 1)"), std::string::npos)
        << e.what();
    EXPECT_NE(std::string(e.what()).find("killed by signal 9"), std::string::npos) << e.what();
  }
  EXPECT_TRUE(children().empty());
  live.reset();
  // A worker that exits without a word, and one whose load fails with SUMO's message.
  set_worker_executable("/bin/false");
  try {
    start_live(road_inputs(), 1, vehicles);
    ADD_FAILURE() << "no error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("closed the connection (exit status 1)"),
              std::string::npos)
        << e.what();
  }
  set_worker_executable(NCOSIM_BINARY);
  SumoInputs bad = road_inputs();
  bad.args[3] = (road().dir / "missing.rou.xml").string();
  try {
    start_live(bad, 1, vehicles);
    ADD_FAILURE() << "no error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("SUMO (live, seed 1): "), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("missing.rou.xml"), std::string::npos) << e.what();
  }
  EXPECT_TRUE(children().empty());
  set_worker_executable("");
  EXPECT_THROW(start_live(road_inputs(), 1, vehicles), std::runtime_error);
  EXPECT_FALSE(libsumo_loaded());
}

TEST(SumoCampaign, SumoErrorsExitTwoWithAClearMessage) {
  ASSERT_TRUE(road().ok);
  struct Case {
    std::string set, expect;
  };
  std::ofstream(road().dir / "bad.rou.xml")
      << R"(<routes><vehicle id="x" route="nowhere" depart="0"/></routes>)";
  const std::vector<Case> cases{
      {"sumo.step=0.0005", "whole number of milliseconds"},
      {"sumo.routes='missing.rou.xml'", "missing.rou.xml' (not found)"},
      {"plant.vehicle='nobody'", "key 'plant.vehicle': vehicle \"nobody\" never drives"},
      {"sumo.routes='bad.rou.xml'",
       "SUMO failed (seed 1): The route 'nowhere' for vehicle 'x' is not known"},
      {"link[0].tx_powr=10", "did you mean 'tx_power'"},
      {"link[0].preset='ns3'", "key 'link[0].preset': expected one of"},
      {"link[0].receiver='leader'", "expected a receiver other than the sender"},
      {"sumo.mode='online'", "key 'sumo.mode'"},
      {"run.recentre='always'", "with a SUMO vehicle as the plant"},
  };
  for (const auto& c : cases) {
    const Output o = run_ncosim("run s.toml --out bad --quiet --set \"" + c.set +
                                "\" --set 'sumo.cache=\"cache_bad\"'");
    EXPECT_EQ(o.code, 2) << c.set << "\n" << o.err;
    EXPECT_NE(o.err.find(c.expect), std::string::npos) << c.set << "\n" << o.err;
    EXPECT_TRUE(o.out.empty()) << o.out;
    EXPECT_FALSE(fs::exists(road().dir / "bad")) << "results written on failure";
  }
  // A range error says what it got, as written (issue 28).
  const Output bounds = run_ncosim(
      "run s.toml --out bad --quiet --set \"link[0].fading='nakagami'\" --set 'link[0].m=[1.0, "
      "2.0]' "
      "--set 'link[0].m_bounds=[-5.0]' --set 'sumo.cache=\"cache_bad\"'");
  EXPECT_EQ(bounds.code, 2) << bounds.err;
  EXPECT_NE(bounds.err.find("expected increasing positive distances (m), got -5"),
            std::string::npos)
      << bounds.err;
  // No `sumo` binary anywhere: exit 2 saying so, and no recording left behind.
  const Output nobin = run_ncosim("run s.toml --out bad --quiet --set 'sumo.cache=\"cache_nobin\"'",
                                  "PATH=/nonexistent SUMO_HOME= ");
  EXPECT_EQ(nobin.code, 2) << nobin.err;
  EXPECT_NE(nobin.err.find("cannot find the `sumo` binary on PATH or in $SUMO_HOME/bin"),
            std::string::npos)
      << nobin.err;
  EXPECT_TRUE(fs::is_empty(road().dir / "cache_nobin"));
}

TEST(SumoCli, ChannelCommandPrintsThePresetsCurve) {
  ASSERT_TRUE(road().ok);
  const Output o = run_ncosim("channel ns3_vanet --csv --max-distance 1000 --step 50");
  ASSERT_EQ(o.code, 0) << o.err;
  std::stringstream ss(o.out);
  std::string line;
  std::getline(ss, line);
  EXPECT_EQ(line, "distance_m,mean_rx_dbm,p_reception");
  const Channel ch = make_preset("ns3_vanet");
  int rows = 0;
  while (std::getline(ss, line)) {
    double d = 0, rx = 0, p = 0;
    ASSERT_EQ(std::sscanf(line.c_str(), "%lf,%lf,%lf", &d, &rx, &p), 3) << line;
    EXPECT_NEAR(p, ch.reception_probability(d), 1e-8) << line;
    ++rows;
  }
  EXPECT_EQ(rows, 21);
  const Output text = run_ncosim("channel cheng2007");
  EXPECT_EQ(text.code, 0);
  EXPECT_NE(text.out.find("no interference model"), std::string::npos);
  EXPECT_NE(text.out.find("802.11p"), std::string::npos);
  const Output bad = run_ncosim("channel nope");
  EXPECT_EQ(bad.code, 2);
  EXPECT_NE(bad.err.find("expected a channel preset"), std::string::npos) << bad.err;
  const Output list = run_ncosim("list");
  EXPECT_NE(list.out.find("sumo_distance"), std::string::npos);
  EXPECT_NE(list.out.find("veins_nakagami3"), std::string::npos);
}

TEST(SumoDistanceLink, DeliveryPerDistanceBinMatchesPd) {
  // Every packet of 40 runs over the scripted road, binned by distance (100 m bins): the
  // delivered count is within 4.5 binomial sigmas of sum p(d) in every bin.
  ASSERT_TRUE(road().ok);
  fs::create_directories(road().dir / "unit");
  auto sc = testing::load_one(road().scenario(), {"sumo.cache=\"unit\"", "run.runs=40"});
  const auto* mobility = dynamic_cast<const Mobility*>(sc->mobility.get());
  ASSERT_NE(mobility, nullptr);
  // summary.csv's model_check calls its losses position-driven, not the designs' model.
  EXPECT_EQ(models::loss_model_of(*sc->links.front().link),
            models::LinkReporting::LossModel::kPosition);
  const Channel ch = make_preset("ns3_vanet");
  const int bins = 12;
  std::vector<double> n(bins), delivered(bins), expected(bins), var(bins);
  const auto period = kernel::seconds_to_time(sc->run.period);
  for (std::uint64_t run = 0; run < 40; ++run) {
    auto m = sc->mobility->start(run);
    auto link = sc->links.front().link->clone();
    kernel::Rng rng = kernel::make_stream(1, run, 0);
    models::bind_run(*link, m.get(), sc->run.seed, run);
    link->reset(rng);
    for (std::int64_t k = 0; k < sc->run.periods; ++k) {
      m->advance(k * period);
      const auto& s = m->vehicle(0);
      const auto& r = m->vehicle(1);
      const std::int64_t outcome = link->transmit(rng);
      if (!s.present || !r.present) {
        EXPECT_EQ(outcome, models::kLost);
        continue;
      }
      const double d = std::hypot(s.x - r.x, s.y - r.y);
      const int b = std::min(bins - 1, static_cast<int>(d / 100.0));
      const double p = ch.reception_probability(d);
      n[b] += 1;
      delivered[b] += outcome != models::kLost;
      expected[b] += p;
      var[b] += p * (1 - p);
      if (outcome != models::kLost) {
        EXPECT_EQ(outcome, 0);  // 802.11p: well under one 100 ms period
      }
    }
  }
  int informative = 0;
  for (int b = 0; b < bins; ++b) {
    if (n[b] == 0) continue;
    SCOPED_TRACE(b);
    EXPECT_LE(std::abs(delivered[b] - expected[b]), 4.5 * std::sqrt(var[b]) + 1.0)
        << delivered[b] << " delivered of " << n[b] << ", expected " << expected[b];
    if (expected[b] / n[b] > 0.05 && expected[b] / n[b] < 0.95 && n[b] > 500) ++informative;
  }
  EXPECT_GE(informative, 3) << "the road does not span the transition of p(d)";
  // The design law is the mean of p(d) over the recorded control instants.
  const double loss = sc->links.front().link->loss_probability();
  EXPECT_GT(loss, 0.05);
  EXPECT_LT(loss, 0.95);
  const auto pmf = sc->links.front().link->delay_pmf(2);
  EXPECT_NEAR(pmf[0], 1.0 - loss, 1e-12);
  EXPECT_EQ(pmf[1], 0.0);
}

TEST(SumoVehiclePlant, TrueStateIsTheVehiclesMotionAndDesignIsConstantVelocity) {
  ASSERT_TRUE(road().ok);
  fs::create_directories(road().dir / "unit");
  auto sc = testing::load_one(road().scenario(), {"sumo.cache=\"unit\""});
  const auto& p = sc->model.plant;
  ASSERT_EQ(p.n(), 2);
  EXPECT_NEAR(p.A(0, 1), 0.1, 1e-15);
  EXPECT_NEAR(p.W(0, 0), 0.1 * 0.1 * 0.1 / 3.0, 1e-15);  // q T^3 / 3
  EXPECT_NEAR(p.W(1, 1), 0.1, 1e-15);
  EXPECT_FALSE(sc->recentre);
  auto m = sc->mobility->start(0);
  m->advance(30 * kernel::kSecond);
  const auto& v = m->vehicle(0);
  EXPECT_TRUE(v.present);
  EXPECT_GT(v.pos, 500.0);  // ~30 m/s for 30 s
  EXPECT_GT(v.speed, 20.0);
  EXPECT_LE(v.speed, 30.0 + 1e-9);
}

TEST(SumoVehiclePlant, ConstantAccelerationModelTracksPositionSpeedAndAcceleration) {
  ASSERT_TRUE(road().ok);
  fs::create_directories(road().dir / "unit");
  auto sc = testing::load_one(
      road().scenario(),
      {"sumo.cache=\"unit\"", "plant.model=\"constant_acceleration\"", "plant.q=0.5",
       "sensor[0].C=[[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]", "run.runs=2"});
  const auto& p = sc->model.plant;
  ASSERT_EQ(p.n(), 3);
  EXPECT_NEAR(p.A(0, 2), 0.005, 1e-15);              // T^2 / 2
  EXPECT_NEAR(p.W(2, 2), 0.5 * 0.1, 1e-15);          // q T
  EXPECT_NEAR(p.W(0, 0), 0.5 * 1e-5 / 20.0, 1e-18);  // q T^5 / 20
  sim::CampaignOptions opt;
  opt.time_estimators = false;
  const auto result = sim::run_campaign(*sc, opt);
  for (const auto& run : result.runs) {
    for (const auto& m : run) {
      EXPECT_FALSE(m.diverged);
      EXPECT_GT(m.count, 0);
    }
  }
}

}  // namespace
}  // namespace ncosim::sumo
