// sim/scenario/scenario_sections.cc — one reader per scenario section
// (sim/scenario/scenario_sections.h).
#include "sim/scenario/scenario_sections.h"

#include <fmt/format.h>

#include <algorithm>
#include <set>
#include <thread>
#include <vector>

#include "kernel/time.h"
#include "lmi/limits.h"
#include "lmi/lmi.h"
#include "sim/scenario/registries.h"
#include "sim/scenario/resource_limits.h"
#include "sim/scenario/scenario_keys.h"

namespace ncosim::sim {

namespace {

std::vector<std::string> link_names(const Scenario& sc) {
  std::vector<std::string> names;
  for (const auto& l : sc.links) names.push_back(l.name);
  return names;
}

// Refuses `packets` on a link that carries fewer in one run (models::Link::packet_bound), at
// key `key` of `t`; `why` says where the count comes from.
void check_packet_bound(const models::Link& link, std::int64_t packets, const config::Table& t,
                        std::string_view key, std::string_view why) {
  const auto bound = link.packet_bound();
  if (bound && bound->packets < packets) {
    t.fail(key, fmt::format("expected a {} of at least {} packets ({}), got {}", bound->noun,
                            packets, why, bound->packets));
  }
}

}  // namespace

config::RunSettings read_run(const config::Table& root) {
  // Without a [run] table every key takes its declared default (run_keys()): the same reads on an
  // empty table, so that the defaults live in the declarations only.
  static const toml::table kNoRun;
  const auto given = root.opt_table("run");
  const config::Table t = given ? *given : config::Table(kNoRun, "run", root.file());
  const config::KeyReader k(t, run_keys());
  config::RunSettings r;
  r.periods = k.integer("periods");
  r.warmup = k.opt_integer("warmup").value_or(default_warmup(r.periods));
  if (r.warmup < 0 || r.warmup >= r.periods) {
    t.fail("warmup", fmt::format("expected an integer in 0..periods-1 ({}), got {}", r.periods - 1,
                                 r.warmup));
  }
  r.runs = k.integer("runs");
  r.seed = static_cast<std::uint64_t>(k.integer("seed"));
  r.period = k.number("period");
  if (kernel::seconds_to_time(r.period) <= 0) {
    t.fail("period", fmt::format("expected a period in seconds in (1e-9, 1e6], got {}", r.period));
  }
  // The integer-ns clock must hold every event time (arrivals may lie beyond the horizon).
  if (static_cast<double>(r.periods) * static_cast<double>(kernel::seconds_to_time(r.period)) >
      4.0e18) {
    t.fail("period",
           fmt::format("expected periods x period <= 4e9 s (the nanosecond clock), got {} x {} s",
                       r.periods, r.period));
  }
  r.recentre = k.string("recentre");
  r.error_curve = k.boolean("error_curve");
  t.finish();
  return r;
}

std::string read_plant(const config::Table& root, const toml::table& doc, Scenario& sc,
                       const models::PlantRegistry& kinds) {
  if (!root.has("plant")) {
    throw config::ScenarioError(config::format_error(
        root.file(), 1, "plant", "expected a [plant] table (required: the plant model), got none"));
  }
  const config::Table plant = root.table("plant");
  const auto& pk = kinds.lookup(plant, "kind", "lti");
  sc.plant_kind = pk.name;
  sc.model.plant = pk.factory(plant, sc.run.period);
  sc.model.period = sc.run.period;
  sc.disturbance = models::read_disturbance(plant, sc.model.plant.nw());
  if (!sc.model.plant.vehicle_key.empty()) {
    if (!sc.mobility)
      plant.fail("kind", fmt::format("expected a [sumo] table for plant kind \"{}\"", pk.name));
    sc.plant_vehicle = sc.mobility->vehicle(plant, sc.model.plant.vehicle_key);
  }
  std::string driver = state_driver(plant, *doc.get("plant")->as_table(), sc.model);
  plant.finish();
  return driver;
}

void read_networks(const config::Table& root, Scenario& sc) {
  sc.networks.read(root, network_registry(), sc.mobility.get());  // network/networks.h
}

namespace {

// Per [[link]]: its attachment to a [[network]] (nullptr: not a node of one).
std::vector<const models::NetworkAttachment*> attachments(const Scenario& sc) {
  std::vector<const models::NetworkAttachment*> out;
  for (const auto& l : sc.links) out.push_back(l.link->network_attachment());
  return out;
}

}  // namespace

void drop_doubled_riders(Scenario& sc) { sc.networks.drop_doubled_riders(attachments(sc)); }

namespace {

// ns-3's work, a lower bound: every packet an application makes costs about 1 us of one core
// (queued or dropped), and every frame on a channel reaches every node's PHY there (ns-3 computes
// each reception), measured at 15 us (wifi) to 100 us (lr_wpan) per frame and node; a channel
// carries at most about 1000 frames a second. So 10 us per reception, 1000 frames/s at most.
constexpr double kPacketSeconds = 1e-6;
constexpr double kReceptionSeconds = 10e-6;
constexpr double kChannelFrames = 1000.0;
// A network worker's own process (the executable, its libraries and ns-3's), measured at 41 MB
// peak RSS for the 802.15.4 star without background.
constexpr double kWorkerBytes = 48e6;

// The background table that drives the work most: its `rate` (packets made) or its nodes.
std::pair<std::size_t, std::string> network_work_driver(const std::vector<config::Table>& tables,
                                                        bool receptions) {
  std::size_t best = 0;
  double most = -1.0;
  for (std::size_t i = 0; i < tables.size(); ++i) {
    const config::Table& t = tables[i];
    const double nodes = static_cast<double>(t.has("nodes") ? t.integer("nodes") : 1);
    const double rate = t.is_string("rate") ? kChannelFrames : t.number("rate");
    const double size = receptions ? nodes : nodes * rate;
    if (size > most) {
      most = size;
      best = i;
    }
  }
  if (!receptions) return {best, "rate"};
  const config::Table& t = tables[best];
  return {best, t.has("nodes") ? "nodes" : t.has("positions") ? "positions" : "network"};
}

// Large networks have a cost too: 10,000 background nodes or a rate of 1e7 packets/s run for
// hours, and packets made faster than a channel carries them wait in its nodes' queues (ns-3's
// 802.15.4 queue has no bound). Refused beyond --max-work and --max-memory before t = 0, naming the
// [[background]] key that drives the estimate (or run.runs when there is none).
void check_network_work(const config::Table& root, const Scenario& sc) {
  if (sc.networks.empty()) return;
  const double seconds_per_run = static_cast<double>(sc.run.periods) * sc.model.period;
  double packets = 0.0, receptions = 0.0, node_bytes = 0.0, queued_bytes = 0.0;
  for (std::size_t n = 0; n < sc.networks.size(); ++n) {
    double made = 0.0, nodes = 1.0, saturated = 0.0;  // nodes: the sink first
    for (const auto& s : sc.model.sensors) {
      const models::NetworkAttachment* a = s.link ? s.link->network_attachment() : nullptr;
      if (a != nullptr && a->network == static_cast<int>(n))
        made += 1.0 / (static_cast<double>(s.spec.every) * sc.model.period);
    }
    for (const auto& l : sc.links) {
      const models::NetworkAttachment* a = l.link->network_attachment();
      if (a != nullptr && a->network == static_cast<int>(n)) nodes += 1.0;
    }
    for (const auto& b : sc.networks.background()) {
      if (b.network != static_cast<int>(n)) continue;
      nodes += 1.0;
      made += b.traffic == network::Traffic::kPoisson ? b.rate : kChannelFrames;
      saturated += b.traffic == network::Traffic::kPoisson ? 0.0 : 1.0;
    }
    packets += made * seconds_per_run;
    receptions += std::min(made, kChannelFrames) * nodes * seconds_per_run;
    const network::NetworkDesign::Footprint f = sc.networks[n].design->footprint();
    node_bytes += nodes * f.node_bytes;
    // A saturated node holds two packets. The others' packets made beyond what the channel
    // carries wait (all of them beside saturated nodes, which keep it busy), up to each queue.
    const double offered = made - kChannelFrames * saturated;
    const double carried = saturated > 0.0 ? 0.0 : f.carried_per_second;
    const double waiting = std::max(0.0, offered - carried) * seconds_per_run;
    queued_bytes += (2.0 * saturated + std::min(waiting, f.queue_packets * nodes)) * f.packet_bytes;
  }
  const double runs = static_cast<double>(sc.run.runs);
  const double seconds = runs * (packets * kPacketSeconds + receptions * kReceptionSeconds);
  const std::string what = fmt::format("{:.3g} packets made and {:.3g} frame receptions in {} runs",
                                       runs * packets, runs * receptions, sc.run.runs);
  // Every run that goes at once holds its networks in a worker of its own.
  const double workers =
      std::min(runs, static_cast<double>(std::max(1U, std::thread::hardware_concurrency())));
  const double bytes = workers * (kWorkerBytes + node_bytes + queued_bytes);
  const std::string held = fmt::format(
      "{} worker(s) at once, each {} for its nodes and {} of waiting packets",
      static_cast<long long>(workers), human_bytes(node_bytes), human_bytes(queued_bytes));
  const auto tables = root.tables("background");
  if (tables.empty()) {
    if (const auto run = root.opt_table("run")) {
      sim::check_network_work(*run, "runs", seconds, what);
      sim::check_network_memory(*run, "runs", bytes, held);
    }
    return;
  }
  const bool by_receptions = receptions * kReceptionSeconds >= packets * kPacketSeconds;
  const auto [i, key] = network_work_driver(tables, by_receptions);
  sim::check_network_work(tables[i], key, seconds, what);
  const auto [j, mkey] = network_work_driver(tables, node_bytes >= queued_bytes);
  sim::check_network_memory(tables[j], mkey, bytes, held);
}

}  // namespace

void check_networks(const config::Table& root, const Scenario& sc) {
  std::vector<char> used(sc.links.size(), 0);
  for (const auto& s : sc.model.sensors) {
    if (s.spec.link >= 0) used[static_cast<std::size_t>(s.spec.link)] = 1;
  }
  for (const auto& a : sc.model.actuators) {
    if (a.spec.link >= 0) used[static_cast<std::size_t>(a.spec.link)] = 1;
  }
  sc.networks.check(root, attachments(sc), used);
  check_network_work(root, sc);
}

void read_links(const config::Table& root, const std::string& dir, Scenario& sc,
                const models::LinkRegistry& kinds) {
  models::LinkContext ctx{dir, sc.run.period, sc.mobility, {}, {}};
  for (const auto& n : sc.networks) ctx.networks.push_back(n.name);
  ctx.check_trace_delay = [&sc](const std::string& trace, int line, std::int64_t delay,
                                const std::string& named_by) {
    check_trace_resources(trace, line, delay, sc.run.runs,
                          named_by);  // sim/scenario/resource_limits.h
  };
  for (const config::Table& t : root.tables("link")) {
    LinkEntry e;
    e.name = config::KeyReader(t, link_common_keys()).string("name");
    if (std::any_of(sc.links.begin(), sc.links.end(),
                    [&](const LinkEntry& l) { return l.name == e.name; })) {
      t.fail("name", fmt::format("expected a unique link name, got \"{}\" twice", e.name));
    }
    const auto& k = kinds.lookup(t, "kind", "");
    e.kind = k.name;
    e.link = k.factory(t, ctx);
    t.finish();
    sc.links.push_back(std::move(e));
  }
}

void read_sensors(const config::Table& root, Scenario& sc) {
  const auto sensor_tables = root.tables("sensor");
  if (sensor_tables.empty())
    root.fail("sensor", "expected at least one [[sensor]] table, got none");
  const std::vector<std::string> links = link_names(sc);
  std::set<std::string> sensor_names;
  for (std::size_t i = 0; i < sensor_tables.size(); ++i) {
    const config::Table& t = sensor_tables[i];
    est::SensorModel sm;
    sm.spec =
        models::read_sensor(t, sc.model.plant, links, static_cast<int>(i), send_policy_registry());
    if (!sensor_names.insert(sm.spec.name).second) {
      t.fail("name", fmt::format("expected a unique sensor name, got \"{}\" twice", sm.spec.name));
    }
    if (sm.spec.link >= 0) sm.link = sc.links[static_cast<std::size_t>(sm.spec.link)].link.get();
    if (sm.link != nullptr && sm.link->independent_copies() && sm.spec.buffer > 0) {
      t.fail(
          "buffer",
          fmt::format("expected buffer = 0 on a link with independent copies (link \"{}\"), got {}",
                      links[static_cast<std::size_t>(sm.spec.link)], sm.spec.buffer));
    }
    t.finish();
    sc.model.sensors.push_back(std::move(sm));
  }
  // A bounded link (a trace) must hold every packet its sensors send in one run.
  const auto link_tables = root.tables("link");
  for (std::size_t l = 0; l < sc.links.size(); ++l) {
    const auto bound = sc.links[l].link->packet_bound();
    if (!bound) continue;
    std::int64_t packets = 0;
    for (const auto& s : sc.model.sensors) {
      if (s.spec.link == static_cast<int>(l))
        packets += (sc.run.periods + s.spec.every - 1) / s.spec.every;
    }
    check_packet_bound(*sc.links[l].link, packets, link_tables[l], bound->key,
                       fmt::format("one run sends {}", packets));
  }
}

void read_actuators(const config::Table& root, Scenario& sc) {
  const auto act_tables = root.tables("actuator");
  if (act_tables.empty()) return;
  const Eigen::Index nu = sc.model.plant.nu();
  if (static_cast<Eigen::Index>(act_tables.size()) != nu) {
    act_tables.back().fail_here(fmt::format(
        "expected one [[actuator]] per input channel ({}), got {}", nu, act_tables.size()));
  }
  if (nu > 16)
    act_tables.back().fail_here(fmt::format("expected at most 16 actuators, got {}", nu));
  if (!sc.model.plant.modes.empty()) {
    act_tables.front().fail_here(
        "expected no [[actuator]] with a jump_linear plant (one mode source per scenario)");
  }
  const std::vector<std::string> links = link_names(sc);
  std::set<std::string> names;
  for (std::size_t i = 0; i < act_tables.size(); ++i) {
    const config::Table& t = act_tables[i];
    est::ActuatorModel am;
    am.spec = models::read_actuator(t, links, static_cast<int>(i));
    if (!names.insert(am.spec.name).second) {
      t.fail("name",
             fmt::format("expected a unique actuator name, got \"{}\" twice", am.spec.name));
    }
    if (am.spec.link >= 0) {
      am.link = sc.links[static_cast<std::size_t>(am.spec.link)].link.get();
      // A network link is one node (sim/run/run.cc, ActuationPath): an actuator's is its own.
      const bool shared = std::any_of(sc.model.sensors.begin(), sc.model.sensors.end(),
                                      [&](const auto& s) { return s.spec.link == am.spec.link; }) ||
                          std::any_of(sc.model.actuators.begin(), sc.model.actuators.end(),
                                      [&](const auto& a) { return a.spec.link == am.spec.link; });
      if (am.link->network_attachment() != nullptr && shared)
        t.fail("link",
               fmt::format("expected a link no [[sensor]] or other [[actuator]] uses: link \"{}\" "
                           "is a node of a [[network]], one node per sender",
                           links[static_cast<std::size_t>(am.spec.link)]));
      if (const models::NetworkAttachment* a = am.link->network_attachment()) {
        const network::NetworkEntry& n = sc.networks[static_cast<std::size_t>(a->network)];
        if (!n.design->carries_actuators() || a->vehicle >= 0 || n.sink_vehicle >= 0)
          t.fail("link", fmt::format("expected a link whose network carries actuator commands: "
                                     "network \"{}\" (kind {}{}) does not",
                                     n.name, n.kind,
                                     n.design->carries_actuators() ? ", a node on a vehicle" : ""));
      }
      check_packet_bound(*am.link, sc.run.periods, t, "link", "one per period");
    }
    t.finish();
    sc.model.actuators.push_back(std::move(am));
  }
}

std::optional<config::Table> read_input(const config::Table& root, Scenario& sc) {
  std::optional<config::Table> input = root.opt_table("input");
  if (!input) return input;
  const auto& ik = input_registry().lookup(*input, "kind", "none");
  sc.input = ik.factory(*input, sc.model.plant);
  sc.input.actuation_delay =
      static_cast<int>(config::KeyReader(*input, input_common_keys()).integer("actuation_delay"));
  if (sc.input.controller) {
    std::vector<models::SensorSpec> specs;
    for (const auto& s : sc.model.sensors) specs.push_back(s.spec);
    sc.input.controller->bind(*input, specs);
  }
  input->finish();
  return input;
}

void read_estimators(const config::Table& root, const toml::table& doc,
                     const std::string& state_driver, Scenario& sc) {
  const auto est_tables = root.tables("estimator");
  if (est_tables.empty())
    root.fail("estimator", "expected at least one [[estimator]] table, got none");
  std::set<std::string> est_names;
  for (std::size_t i = 0; i < est_tables.size(); ++i) {
    const config::Table& t = est_tables[i];
    EstimatorEntry e;
    const auto& k = estimator_registry().lookup(t, "kind", "");
    e.kind = k.name;
    if (sc.model.is_nonlinear() && !estimator_registry().accepts_nonlinear(k.name))
      t.fail("kind", fmt::format("the {} estimator needs a linear model, and the {} is nonlinear",
                                 k.name, sc.model.plant.nonlinear ? "plant" : "sensors' output"));
    const config::KeyReader common(t, estimator_common_keys());
    e.name = common.opt_string("name").value_or(fmt::format("{} {}", e.kind, i));
    if (!est_names.insert(e.name).second) {
      t.fail("name", fmt::format("expected a unique estimator name, got \"{}\" twice", e.name));
    }
    // One of the row statuses of summary.csv (results/README.md `### status`).
    e.expected_status = common.opt_string("expected_status").value_or("");
    const toml::table& raw = *doc.get("estimator")->as_array()->get(i)->as_table();
    check_estimator_resources(t, k.name,
                              estimator_registry().cost(k.name, t, raw, sc.model, state_driver),
                              state_driver);  // sim/scenario/resource_limits.h
    try {
      const lmi::ScopedSolveObserver note(
          large_solve_note(t, k.name, state_driver));  // sim/scenario/resource_limits.h
      e.design = k.factory(t, sc.model);
    } catch (const lmi::ResourceLimitError& err) {
      t.fail("kind",
             fmt::format("the {} design: {}{}; its size is driven by {}", k.name, err.what(),
                         err.address_space ? "" : " (--max-memory / --max-work raise the limits)",
                         state_driver));
    } catch (const lmi::Error& err) {
      // The model's numbers make the LMIs meaningless (e.g. an overflow to inf): bad input.
      t.fail("kind",
             fmt::format(
                 "the {} design cannot be posed for this model: {} (check the magnitudes of the "
                 "plant, sensor and noise values)",
                 k.name, err.what()));
    }
    t.finish();
    sc.estimators.push_back(std::move(e));
  }
}

void bind_feedback_source(const std::optional<config::Table>& input, Scenario& sc) {
  if (sc.input.source.empty()) return;  // the input reads no estimate
  for (std::size_t i = 0; i < sc.estimators.size(); ++i) {
    if (sc.estimators[i].name == sc.input.source) sc.input.source_index = static_cast<int>(i);
  }
  if (sc.input.source_index >= 0) return;
  std::vector<std::string> names{"plant"};
  for (const auto& e : sc.estimators) names.push_back(e.name);
  std::string list;
  for (const auto& n : names) list += (list.empty() ? "" : ", ") + fmt::format("\"{}\"", n);
  const std::string hint = config::did_you_mean(sc.input.source, names);
  input->fail(sc.input.controller->source_key(),
              fmt::format("expected \"plant\" or an estimator name ({}), got \"{}\"{}", list,
                          sc.input.source,
                          hint.empty() ? "" : fmt::format(" (did you mean \"{}\"?)", hint)));
}

void choose_recentre(const config::Table& root, Scenario& sc) {
  // Re-centring: an open-loop unstable plant is simulated in coordinates that the known
  // input keeps bounded; the estimation error is unchanged (scenarios/README.md).
  const bool unstable = sc.model.plant.spectral_radius() >= 1.0;
  const bool feedback = sc.input.controller->closes_loop();
  // Send-on-delta sensors decide on the output itself: re-centring would change what they send.
  bool send_on_delta = false;
  for (const auto& sm : sc.model.sensors) {
    send_on_delta = send_on_delta || !sm.spec.policy->sends_every_sample();
  }
  auto refuse = [&](const std::string& why) { root.table("run").fail("recentre", why); };
  if (sc.plant_vehicle >= 0) {
    // The true state comes from the mobility source: nothing to re-centre.
    if (sc.run.recentre == "always")
      refuse("expected \"auto\" or \"never\" with a SUMO vehicle as the plant");
  } else if (sc.run.recentre == "always") {
    sc.recentre = true;
    if (send_on_delta) {
      refuse(
          "expected \"auto\" or \"never\" with send-on-delta sensors (they would decide on "
          "re-centred "
          "outputs), got \"always\"");
    }
  } else if (sc.run.recentre == "auto") {
    sc.recentre = unstable && !feedback && !send_on_delta;
  }
  if (sc.recentre && feedback && sc.input.source_index >= 0) {
    refuse(fmt::format(
        "expected \"auto\" or \"never\" with feedback on an estimate (input.source = \"{}\"), got "
        "\"always\" (the controller would see re-centred estimates)",
        sc.input.source));
  }
  if (sc.recentre && sc.input.controller->sees_outputs()) {
    refuse(
        "expected \"auto\" or \"never\" with a controller input (it would see re-centred outputs), "
        "got "
        "\"always\"");
  }
}

PairedSettings read_paired(const config::Table& root, const toml::table& doc, const Scenario& sc) {
  PairedSettings p;
  p.file = root.file();
  const auto t = root.opt_table("paired");
  if (!t) return p;
  const config::KeyReader keys(*t, paired_keys());
  if (const auto reference = keys.opt_string("reference")) {
    p.reference = *reference;
    p.reference_line = t->line_of("reference");
    std::vector<std::string> names;
    for (const auto& e : sc.estimators) names.push_back(e.name);
    if (std::find(names.begin(), names.end(), p.reference) == names.end()) {
      std::string list;
      for (const auto& n : names) list += (list.empty() ? "" : ", ") + fmt::format("\"{}\"", n);
      const std::string hint = config::did_you_mean(p.reference, names);
      t->fail("reference",
              fmt::format("expected an estimator name ({}), got \"{}\"{}", list, p.reference,
                          hint.empty() ? "" : fmt::format(" (did you mean \"{}\"?)", hint)));
    }
  }
  // reference_case: a table of key paths and values of any type, read from the document itself.
  t->allow("reference_case");
  if (keys.has("reference_case")) {
    const toml::node* n = doc.at_path("paired.reference_case").node();
    p.reference_case_line = t->line_of("reference_case");
    if (n == nullptr || !n->is_table()) {
      t->fail("reference_case",
              fmt::format("expected a table of sweep key paths and values, e.g. "
                          "{{ \"link[0].preset\" = \"ns3_vanet\" }}, got {}",
                          n == nullptr ? std::string("nothing") : config::describe(*n)));
    }
    for (auto&& [k, v] : *n->as_table()) {
      const auto s = v.value_exact<std::string>();
      p.reference_case.emplace_back(std::string(k.str()), s ? *s : config::compact_toml(v));
    }
  }
  t->finish();
  return p;
}

}  // namespace ncosim::sim
