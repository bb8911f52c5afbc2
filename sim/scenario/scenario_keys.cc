// sim/scenario/scenario_keys.cc — the scenario's own sections declared as data
// (sim/scenario/scenario_keys.h).
#include "sim/scenario/scenario_keys.h"

#include <fmt/format.h>

#include <algorithm>

#include "models/actuator.h"
#include "models/sensor.h"
#include "sim/scenario/registries.h"
#include "sim/scenario/scenario_types.h"

namespace ncosim::sim {

const config::Keys& top_level_keys() {
  static const config::Keys keys{
      config::Key::string("title")
          .optional("the file name without extension")
          .help("heading of summary.md, title in manifest.json"),
      config::Key::table("run").optional("all defaults").help("the campaign"),
      config::Key::tables("sweep").optional("none").help(
          "parameter sweep (cartesian product of cases)"),
      config::Key::table("plant").help("the plant (required)"),
      config::Key::tables("link").optional("none").help(
          "links, referred to by name from [[sensor]] and [[actuator]]"),
      config::Key::tables("sensor").help("sensors, in order (required, at least one)"),
      config::Key::table("input").optional("u = 0").help("the plant input"),
      config::Key::tables("estimator").help("estimators, in order, one output row each (required)"),
      config::Key::tables("actuator")
          .optional("ideal actuation")
          .help("controller-to-actuator links, one per input channel in input order"),
      config::Key::table("sumo").optional("none").help("vehicle mobility from SUMO"),
      config::Key::tables("network").optional("none").help(
          "packet-level networks (ns-3); a [[link]] of kind network is a node of one"),
      config::Key::tables("background")
          .optional("none")
          .help("background traffic nodes of a [[network]]: their packets contend with the "
                "sensors' and are counted, never given to an estimator"),
      config::Key::table("paired")
          .optional("defaults")
          .help("the reference of the paired columns of summary.csv"),
  };
  return keys;
}

namespace {
constexpr std::int64_t kWarmupCap = 100;  // the default warm-up: min(100, periods / 10)
}  // namespace

std::int64_t default_warmup(std::int64_t periods) { return std::min(kWarmupCap, periods / 10); }

const config::Keys& run_keys() {
  static const config::Keys keys{
      config::Key::integer("periods")
          .range(1, 1'000'000'000)
          .says("an integer in 1..1000000000 (1e9)")
          .or_default(10000)
          .unit("periods")
          .help("control periods per Monte Carlo run: k = 0 .. periods-1"),
      config::Key::integer("warmup")
          .optional(fmt::format("min({}, periods / 10)", kWarmupCap))
          .unit("periods")
          .help("the first warmup periods are left out of every metric; 0 .. periods-1"),
      config::Key::integer("runs")
          .range(1, 10'000'000)
          .says("an integer in 1..10000000 (1e7)")
          .or_default(10)
          .help("Monte Carlo runs"),
      config::Key::integer("seed")
          .min(0)
          .says("a non-negative integer")
          .or_default(1)
          .help("campaign seed; run r uses the streams of (seed, r)"),
      config::Key::number("period")
          .above(0.0)
          .max(1e6)
          .says("a period in seconds in (1e-9, 1e6]")
          .or_default(1.0)
          .unit("s")
          .help("control period: the integer-ns clock step and the discretisation step of "
                "lti_continuous; at least 1 ns once rounded to whole nanoseconds (periods x "
                "period <= 4e9 s)"),
      config::Key::choice("recentre", {"auto", "always", "never"})
          .or_default("auto")
          .help("re-centring of open-loop-unstable plants (see Re-centring below)"),
      config::Key::boolean("error_curve")
          .or_default(false)
          .help("also write error_curve.csv: every estimator's run-averaged squared error per "
                "period with its 95 % band (results/README.md); costs 16 bytes x periods x "
                "estimators x (states + 1) of memory per thread"),
  };
  return keys;
}

namespace {

// [plant.disturbance] (read by models::read_disturbance).
const config::Keys& disturbance_keys() {
  static const config::Keys sine{
      config::Key::vector("amplitude").help("1 or nw entries"),
      config::Key::number("omega").unit("rad/s").help("angular frequency (per period k)"),
      config::Key::number("phase").or_default(0.0).unit("rad").help("phase"),
  };
  static const config::Keys keys{
      config::Key::vector("offset").optional("zeros").help("constant offset, 1 or nw entries"),
      config::Key::tables("sine").optional("none").fields(sine).help(
          "[[plant.disturbance.sine]]: amplitude * sin(omega k + phase) each"),
  };
  return keys;
}

}  // namespace

const config::Keys& plant_common_keys() {
  static const config::Keys keys{
      config::Key::string("kind").optional("\"lti\"").help("the plant kind (below)"),
      config::Key::table("disturbance")
          .optional("none")
          .fields(disturbance_keys())
          .help("deterministic disturbance added to w: offset (1 or nw entries) and [[sine]] "
                "tables (amplitude, omega in rad/s, phase)"),
  };
  return keys;
}

const config::Keys& sensor_common_keys() { return models::sensor_keys(); }

const config::Keys& link_common_keys() {
  static const config::Keys keys{
      config::Key::string("name").help("unique among links; [[sensor]] and [[actuator]] name it"),
      config::Key::string("kind").help("the link kind (below)"),
  };
  return keys;
}

// Read by the network layer (network/networks.h), declared there.
const config::Keys& network_common_keys() { return network::network_keys(); }
const config::Keys& background_keys() { return network::background_keys(); }

const config::Keys& actuator_keys() { return models::actuator_keys(); }

const config::Keys& input_common_keys() {
  static const config::Keys keys{
      config::Key::string("kind").optional("\"none\"").help("the input kind (below)"),
      config::Key::integer("actuation_delay")
          .range(0, 1000)
          .says("an integer in 0..1000 (periods)")
          .or_default(0)
          .unit("periods")
          .help("periods between computing an input and applying it"),
  };
  return keys;
}

const config::Keys& estimator_common_keys() {
  static const config::Keys keys{
      config::Key::string("kind").help("the estimator kind (below)"),
      config::Key::string("name")
          .optional("\"<kind> <i>\" (0-based position, e.g. \"jump 0\")")
          .help("the row name in every output; unique among estimators"),
      config::Key::choice("expected_status", expected_status_values())
          .optional("\"ok\"")
          .help("the status this row is expected to have (design_failed: any design_<status>); "
                "run --fail-on-status fails only on rows whose status differs"),
  };
  return keys;
}

const config::Keys& sweep_keys() {
  static const config::Keys keys{
      config::Key::string("key").help(
          "the key path of the value to vary (not into sweep itself; each key once)"),
      config::Key::array("values")
          .entries(1, 0)
          .says("a non-empty array of values")
          .help("the values, in order: non-empty, each valid for the key"),
      config::Key::string("zip")
          .optional("none (an axis of its own)")
          .help("sweeps sharing a zip name move together (equal lengths) as one axis"),
  };
  return keys;
}

const config::Keys& sumo_keys() {
  static const config::Keys keys =
      config::Keys{
          config::Key::string("config")
              .optional("none: `net` and `routes`")
              .help("SUMO configuration (.sumocfg; this or `net` is required): its net-file, "
                    "route-files and additional-files must exist (those files are hashed)"),
          config::Key::string("net").optional("none").help("road network (-n), with `routes`"),
          config::Key::string("routes").optional("none").help("routes (-r): required with `net`"),
          config::Key::string("additional").optional("none").help("additional file (-a)"),
          config::Key::number("step").above(0.0).max(3600.0).or_default(0.1).unit("s").help(
              "SUMO step length: a whole number of milliseconds (SUMO time is integer ms; "
              "anything else is an error, not rounded)"),
          config::Key::integer("seeds").range(1, 100000).or_default(1).help(
              "mobility realisations"),
          config::Key::integer("seed")
              .range(0, 2147483647)
              .or_default(1)
              .help("SUMO seed of realisation 0 (realisation s uses seed + s; seed + seeds <= "
                    "2^31 - 1)"),
          config::Key::choice("mode", {"replay", "live"})
              .or_default("replay")
              .help("replay: recordings of the sumo binary; live: libsumo in a worker per run"),
          config::Key::string("cache")
              .optional("$NCOSIM_SUMO_CACHE, else $XDG_CACHE_HOME/ncosim/sumo, else "
                        "~/.cache/ncosim/sumo")
              .help("recording cache, a folder that can be created"),
      }
          .require_one_of({"config", "net"});
  return keys;
}

const config::Keys& paired_keys() {
  static const config::Keys keys{
      config::Key::string("reference")
          .optional("the first Kalman-type row whose status is ok, else the first ok row")
          .help("the name of the reference estimator of the paired columns"),
      config::Key::table("reference_case")
          .optional("the first case")
          .help("{ \"KEY PATH\" = VALUE, ... }: the reference case among the swept values"),
  };
  return keys;
}

namespace {

template <class R>
std::vector<SectionKind> kinds_of(const R& registry) {
  std::vector<SectionKind> out;
  for (const auto& e : registry.entries()) out.push_back({e.name, e.help, &e.keys, e.declared});
  return out;
}

}  // namespace

std::vector<Section> scenario_sections() {
  std::vector<Section> s;
  const config::Keys& top = top_level_keys();
  auto add = [&](const char* key, bool array, const config::Keys* keys) -> Section& {
    Section& x = s.emplace_back();
    x.key = key;
    x.array = array;
    x.required = top.at(key).required();
    x.help = top.at(key).help_text();
    x.keys = keys;
    return x;
  };
  add("run", false, &run_keys());
  add("sweep", true, &sweep_keys());
  Section& plant = add("plant", false, &plant_common_keys());
  plant.kind_key = "kind";
  plant.default_kind = "lti";
  plant.kinds = kinds_of(plant_registry());
  Section& link = add("link", true, &link_common_keys());
  link.kind_key = "kind";
  link.kinds = kinds_of(link_registry());
  Section& sensor = add("sensor", true, &sensor_common_keys());
  sensor.kind_key = "policy";
  sensor.default_kind = "periodic";
  sensor.kinds = kinds_of(send_policy_registry());
  Section& input = add("input", false, &input_common_keys());
  input.kind_key = "kind";
  input.default_kind = "none";
  input.kinds = kinds_of(input_registry());
  Section& est = add("estimator", true, &estimator_common_keys());
  est.kind_key = "kind";
  est.kinds = kinds_of(estimator_registry());
  add("actuator", true, &actuator_keys());
  add("sumo", false, &sumo_keys());
  Section& network = add("network", true, &network_common_keys());
  network.kind_key = "kind";
  network.kinds = kinds_of(network_registry());
  add("background", true, &background_keys());
  add("paired", false, &paired_keys());
  return s;
}

std::string missing_section_message(const Section& section) {
  if (section.array)
    return fmt::format("expected at least one [[{}]] table, got none", section.key);
  return fmt::format("expected a [{}] table (required: {}), got none", section.key,
                     section.key == "plant" ? std::string("the plant model") : section.help);
}

std::vector<NamedKeys> section_keys() {
  return {{"section.top", &top_level_keys()},
          {"section.run", &run_keys()},
          {"section.plant", &plant_common_keys()},
          {"section.sensor", &sensor_common_keys()},
          {"section.link", &link_common_keys()},
          {"section.actuator", &actuator_keys()},
          {"section.input", &input_common_keys()},
          {"section.estimator", &estimator_common_keys()},
          {"section.sweep", &sweep_keys()},
          {"section.paired", &paired_keys()},
          {"section.sumo", &sumo_keys()},
          {"section.network", &network_common_keys()},
          {"section.background", &background_keys()}};
}

}  // namespace ncosim::sim
