// tests/sim/scenario_sections_test.cc — the scenario reader in process, one section reader at a
// time (sim/scenario/scenario_sections.h), and the component hooks it asks instead of switching on
// kinds: a plant that names a mobility vehicle, a link that carries a bounded number of packets.
// The hooks are exercised with kinds registered in local registries (no global state).
#include "sim/scenario/scenario_sections.h"

#include <gtest/gtest.h>

#include <memory>
#include <string>

#include "error_of.h"
#include "models/link.h"
#include "sim/scenario/scenario.h"
#include "sim/scenario/scenario_keys.h"

namespace ncosim::sim {
namespace {

using testing::error_of;
toml::table parse(const std::string& text) { return testing::parse_toml(text); }

// A stable two-state plant with one input (Dolz et al. 2014, system A1): lines 1-6 of every
// scenario below ([plant] on line 2), so a key written next is on line 7 or later.
const std::string kPlant = R"(
[plant]
A  = [[0.8821, -0.0351], [-0.0351, 0.7347]]
Bu = [[-0.3359], [0.3466]]
Bw = [[0.0121, 0.1347], [0.0112, 0.0831]]
W  = [[0.2632, -0.0027], [-0.0027, 0.2466]]
)";

// The sections read in build_scenario()'s order up to (and including) the sensors.
struct Reader {
  toml::table doc;
  config::Table root;
  Scenario sc;
  explicit Reader(const std::string& text) : doc(parse(text)), root(doc, "", "s.toml") {
    sc.file = "s.toml";
  }
  std::string plant() {
    sc.run = read_run(root);
    return read_plant(root, doc, sc);
  }
  // The sections up to the links, with the link kinds of `kinds`.
  void links(const models::LinkRegistry& kinds) {
    plant();
    read_links(root, ".", sc, kinds);
  }
};

TEST(ReadRun, DefaultsWithoutTheTable) {
  const toml::table doc = parse("title = \"x\"\n");
  const config::RunSettings r = read_run(config::Table(doc, "", "s.toml"));
  EXPECT_EQ(r.periods, 10000);
  EXPECT_EQ(r.warmup, 100);
  EXPECT_EQ(r.runs, 10);
  EXPECT_EQ(r.seed, 1u);
  EXPECT_EQ(r.period, 1.0);
  EXPECT_EQ(r.recentre, "auto");
}

TEST(ReadRun, TheInitialisersOfRunSettingsAreTheDeclaredDefaults) {
  // read_run takes every default from run_keys(); RunSettings' own initialisers (for code that
  // builds settings without a scenario) must say the same.
  const toml::table doc = parse("title = \"x\"\n");
  const config::RunSettings read = read_run(config::Table(doc, "", "s.toml"));
  const config::RunSettings plain;
  EXPECT_EQ(plain.periods, read.periods);
  EXPECT_EQ(plain.warmup, read.warmup);
  EXPECT_EQ(plain.runs, read.runs);
  EXPECT_EQ(plain.seed, read.seed);
  EXPECT_EQ(plain.period, read.period);
  EXPECT_EQ(plain.recentre, read.recentre);
  EXPECT_EQ(plain.error_curve, read.error_curve);
  const config::Keys& k = run_keys();
  EXPECT_EQ(plain.periods, std::get<std::int64_t>(k.at("periods").default_value()));
  EXPECT_EQ(plain.warmup, default_warmup(plain.periods));
  EXPECT_EQ(plain.runs, std::get<std::int64_t>(k.at("runs").default_value()));
  EXPECT_EQ(static_cast<std::int64_t>(plain.seed),
            std::get<std::int64_t>(k.at("seed").default_value()));
  EXPECT_EQ(plain.period, std::get<double>(k.at("period").default_value()));
  EXPECT_EQ(plain.recentre, std::get<std::string>(k.at("recentre").default_value()));
  EXPECT_EQ(plain.error_curve, std::get<bool>(k.at("error_curve").default_value()));
}

TEST(ReadRun, WarmupDefaultsToATenthOfAShortHorizon) {
  // periods = 50: the default warm-up min(100, 50 / 10) = 5.
  const toml::table doc = parse("[run]\nperiods = 50\n");
  EXPECT_EQ(read_run(config::Table(doc, "", "s.toml")).warmup, 5);
}

TEST(ReadRun, RangeErrorsAndUnknownKeysNameFileLineAndKey) {
  const toml::table runs = parse("[run]\nperiods = 10\nruns = 0\n");
  EXPECT_EQ(error_of([&] { (void)read_run(config::Table(runs, "", "s.toml")); }),
            "s.toml:3: key 'run.runs': expected an integer in 1..10000000 (1e7), got 0");
  const toml::table warmup = parse("[run]\nperiods = 10\nwarmup = 10\n");
  EXPECT_EQ(error_of([&] { (void)read_run(config::Table(warmup, "", "s.toml")); }),
            "s.toml:3: key 'run.warmup': expected an integer in 0..periods-1 (9), got 10");
  const toml::table typo = parse("[run]\nperiod = 0.5\nsed = 3\n");
  EXPECT_EQ(error_of([&] { (void)read_run(config::Table(typo, "", "s.toml")); }),
            "s.toml:3: key 'run.sed': unknown key (did you mean 'seed'?)");
}

TEST(ReadPlant, IsRequiredAndDefaultsToLti) {
  Reader none("[run]\nruns = 2\n");
  EXPECT_EQ(
      error_of([&] { none.plant(); }),
      "s.toml:1: key 'plant': expected a [plant] table (required: the plant model), got none");
  Reader lti(kPlant);
  EXPECT_EQ(lti.plant(), "plant.A (2 plant states)");
  EXPECT_EQ(lti.sc.plant_kind, "lti");
  EXPECT_EQ(lti.sc.model.plant.n(), 2);
  EXPECT_EQ(lti.sc.model.plant.nu(), 1);
  EXPECT_EQ(lti.sc.plant_vehicle, -1);
}

// A mobility source with one vehicle per name, at index 3 + the order of asking.
class FakeMobility final : public models::MobilitySource {
 public:
  std::unique_ptr<models::MobilityRun> start(std::uint64_t) const override { return nullptr; }
  bool single_threaded() const override { return false; }
  int vehicle(const config::Table& t, std::string_view key) override {
    names.push_back(t.string(key));
    return 2 + static_cast<int>(names.size());
  }
  std::vector<int> every_vehicle(const config::Table&, std::string_view) override { return {}; }
  void prepare() override {}
  std::vector<std::string> names;
};

// A plant kind whose true state is a vehicle's motion: it names the key (models::LinearPlant::
// vehicle_key) and the reader binds it to the mobility source, whatever the kind is called.
models::PlantRegistry vehicle_plants() {
  models::PlantRegistry r;
  r.add("tracked", "a vehicle's motion", [](const config::Table& t, double) {
    models::LinearPlant p;
    p.A = Eigen::MatrixXd::Identity(1, 1);
    p.Bu = Eigen::MatrixXd::Zero(1, 0);
    p.Bw = p.W = p.A;
    p.x0 = Eigen::VectorXd::Zero(1);
    p.vehicle_key = "car";
    (void)t;
    return p;
  });
  return r;
}

TEST(ReadPlant, APlantThatNamesAVehicleIsBoundToTheMobilitySource) {
  const auto kinds = vehicle_plants();
  Reader without("[plant]\nkind = \"tracked\"\ncar = \"veh0\"\n");
  without.sc.run = read_run(without.root);
  EXPECT_EQ(error_of([&] { read_plant(without.root, without.doc, without.sc, kinds); }),
            "s.toml:2: key 'plant.kind': expected a [sumo] table for plant kind \"tracked\"");
  Reader with("[plant]\nkind = \"tracked\"\ncar = \"veh0\"\n");
  auto mobility = std::make_shared<FakeMobility>();
  with.sc.mobility = mobility;
  with.sc.run = read_run(with.root);
  (void)read_plant(with.root, with.doc, with.sc, kinds);
  EXPECT_EQ(with.sc.plant_vehicle, 3);
  EXPECT_EQ(mobility->names, std::vector<std::string>{"veh0"});
}

// A link that carries at most `capacity` packets a run (like a replayed trace).
class BoundedLink final : public models::Link {
 public:
  explicit BoundedLink(std::int64_t capacity) : capacity_(capacity) {}
  std::unique_ptr<Link> clone() const override { return std::make_unique<BoundedLink>(*this); }
  std::int64_t transmit(kernel::Rng&) override { return 0; }
  std::vector<double> delay_pmf(int max_delay) const override {
    std::vector<double> p(static_cast<std::size_t>(max_delay) + 1, 0.0);
    p[0] = 1.0;
    return p;
  }
  double loss_probability() const override { return 0.0; }
  std::optional<PacketBound> packet_bound() const override {
    return PacketBound{capacity_, "capacity", "recording"};
  }

 private:
  std::int64_t capacity_;
};

models::LinkRegistry bounded_links() {
  models::LinkRegistry r;
  r.add(
      "bounded", "at most `capacity` packets",
      [](const config::Table& t, const models::LinkContext&) {
        return std::unique_ptr<models::Link>(std::make_unique<BoundedLink>(t.integer("capacity")));
      });
  return r;
}

TEST(ReadLinks, NamesAreUniqueAndKindsRegistered) {
  Reader twice(kPlant +
               "[[link]]\nname = \"a\"\nkind = \"bernoulli\"\nloss = 0.1\n"
               "[[link]]\nname = \"a\"\nkind = \"bernoulli\"\nloss = 0.2\n");
  twice.plant();
  EXPECT_EQ(error_of([&] { read_links(twice.root, ".", twice.sc); }),
            "s.toml:12: key 'link[1].name': expected a unique link name, got \"a\" twice");
  Reader unknown(kPlant + "[[link]]\nname = \"a\"\nkind = \"bounded\"\n");
  unknown.plant();
  const std::string e = error_of([&] { read_links(unknown.root, ".", unknown.sc); });
  EXPECT_EQ(e.rfind("s.toml:9: key 'link[0].kind': expected one of \"delay\", ", 0), 0u) << e;
}

TEST(ReadSensors, ABoundedLinkMustCarryEveryPacketItsSensorsSend) {
  // 10 periods: the sensor sending every period sends 10 packets, the one sending every 3rd
  // sends ceil(10 / 3) = 4; together 14 on the link, which carries 13.
  const std::string text = kPlant + R"(
[run]
periods = 10
[[link]]
name = "rec"
kind = "bounded"
capacity = 13
[[sensor]]
C = [[1.0, 0.0]]
R = [[0.1]]
link = "rec"
[[sensor]]
C = [[0.0, 1.0]]
R = [[0.1]]
link = "rec"
every = 3
)";
  Reader r(text);
  r.links(bounded_links());
  EXPECT_EQ(error_of([&] { read_sensors(r.root, r.sc); }),
            "s.toml:13: key 'link[0].capacity': expected a recording of at least 14 packets (one "
            "run sends 14), "
            "got 13");
  // With 14 it holds.
  Reader ok(std::string(text).replace(text.find("capacity = 13"), 13, "capacity = 14"));
  ok.links(bounded_links());
  read_sensors(ok.root, ok.sc);
  ASSERT_EQ(ok.sc.model.sensors.size(), 2u);
  EXPECT_EQ(ok.sc.model.sensors[1].link, ok.sc.links[0].link.get());
  EXPECT_EQ(ok.sc.model.sensors[1].spec.every, 3);
}

TEST(ReadSensors, AtLeastOneWithUniqueNames) {
  Reader none(kPlant);
  none.plant();
  EXPECT_EQ(error_of([&] { read_sensors(none.root, none.sc); }),
            "s.toml:1: key 'sensor': expected at least one [[sensor]] table, got none");
  Reader twice(kPlant +
               "[[sensor]]\nname = \"y\"\nC = [[1.0, 0.0]]\nR = [[0.1]]\n"
               "[[sensor]]\nname = \"y\"\nC = [[0.0, 1.0]]\nR = [[0.1]]\n");
  twice.plant();
  EXPECT_EQ(error_of([&] { read_sensors(twice.root, twice.sc); }),
            "s.toml:12: key 'sensor[1].name': expected a unique sensor name, got \"y\" twice");
}

TEST(ReadActuators, OnePerInputChannelAndBoundedLinksCarryOnePerPeriod) {
  const std::string base = kPlant + R"(
[run]
periods = 10
[[link]]
name = "rec"
kind = "bounded"
capacity = 9
)";
  Reader r(base + "[[actuator]]\nlink = \"rec\"\n");
  r.links(bounded_links());
  EXPECT_EQ(error_of([&] { read_actuators(r.root, r.sc); }),
            "s.toml:15: key 'actuator[0].link': expected a recording of at least 10 packets (one "
            "per period), got 9");
  Reader two(base + "[[actuator]]\nlink = \"rec\"\n[[actuator]]\nlink = \"rec\"\n");
  two.links(bounded_links());
  EXPECT_EQ(error_of([&] { read_actuators(two.root, two.sc); }),
            "s.toml:16: key 'actuator[1]': expected one [[actuator]] per input channel (1), got 2");
  Reader none(base);
  none.plant();
  read_actuators(none.root, none.sc);
  EXPECT_TRUE(none.sc.model.actuators.empty());
}

// The sections after the sensors, on a scenario whose input reads an estimate.
std::string with_feedback(const std::string& source, const std::string& recentre) {
  return kPlant + "[run]\nperiods = 20\nrecentre = \"" + recentre + R"("
[[sensor]]
C = [[1.0, 0.0]]
R = [[0.1]]
[input]
kind = "state_feedback"
K = [[0.1, 0.1]]
source = ")" +
         source + R"("
[[estimator]]
name = "open"
kind = "open_loop"
)";
}

TEST(ReadInputAndEstimators, TheFeedbackSourceIsAnEstimatorByName) {
  Reader r(with_feedback("open", "auto"));
  const std::string driver = r.plant();
  read_sensors(r.root, r.sc);
  const auto input = read_input(r.root, r.sc);
  ASSERT_TRUE(input.has_value());
  read_estimators(r.root, r.doc, driver, r.sc);
  ASSERT_EQ(r.sc.estimators.size(), 1u);
  EXPECT_EQ(r.sc.estimators[0].kind, "open_loop");
  bind_feedback_source(input, r.sc);
  EXPECT_EQ(r.sc.input.source_index, 0);

  Reader typo(with_feedback("opne", "auto"));
  const std::string d2 = typo.plant();
  read_sensors(typo.root, typo.sc);
  const auto in2 = read_input(typo.root, typo.sc);
  read_estimators(typo.root, typo.doc, d2, typo.sc);
  EXPECT_EQ(error_of([&] { bind_feedback_source(in2, typo.sc); }),
            "s.toml:16: key 'input.source': expected \"plant\" or an estimator name (\"plant\", "
            "\"open\"), got "
            "\"opne\" (did you mean \"open\"?)");
}

TEST(ChooseRecentre, OnlyAnOpenLoopUnstablePlantIsRecentredByDefault) {
  auto decide = [](const std::string& a, const std::string& recentre) {
    std::string text = kPlant + "[run]\nrecentre = \"" + recentre +
                       "\"\n[[sensor]]\nC = [[1.0, 0.0]]\nR = [[0.1]]\n";
    const std::string a1 = "[[0.8821, -0.0351], [-0.0351, 0.7347]]";
    text.replace(text.find(a1), a1.size(), a);
    Reader r(text);
    r.plant();
    read_sensors(r.root, r.sc);
    choose_recentre(r.root, r.sc);
    return r.sc.recentre;
  };
  const std::string stable = "[[0.5, 0.0], [0.0, 0.5]]", unstable = "[[1.2, 0.0], [0.0, 0.5]]";
  EXPECT_FALSE(decide(stable, "auto"));
  EXPECT_TRUE(decide(unstable, "auto"));  // spectral radius 1.2 >= 1, no feedback
  EXPECT_FALSE(decide(unstable, "never"));
  EXPECT_TRUE(decide(stable, "always"));
  // Feedback on an estimate forbids "always" (the controller would see re-centred estimates).
  Reader r(with_feedback("open", "always"));
  const std::string driver = r.plant();
  read_sensors(r.root, r.sc);
  const auto input = read_input(r.root, r.sc);
  read_estimators(r.root, r.doc, driver, r.sc);
  bind_feedback_source(input, r.sc);
  EXPECT_EQ(error_of([&] { choose_recentre(r.root, r.sc); }),
            "s.toml:9: key 'run.recentre': expected \"auto\" or \"never\" with feedback on an "
            "estimate (input.source "
            "= \"open\"), got \"always\" (the controller would see re-centred estimates)");
}

TEST(BuildScenario, ReadsEverySectionOfTheFlagship) {
  const std::string file = std::string(NCOSIM_SOURCE_DIR) + "/scenarios/dolz2014_table2.toml";
  const toml::table doc = toml::parse_file(file);
  const auto sc = build_scenario(doc, file, std::string(NCOSIM_SOURCE_DIR) + "/scenarios");
  EXPECT_EQ(sc->links.size(), 2u);
  EXPECT_EQ(sc->model.sensors.size(), 2u);
  EXPECT_EQ(sc->estimators.size(), 7u);
  EXPECT_EQ(sc->run.runs, 20);
}

}  // namespace
}  // namespace ncosim::sim
