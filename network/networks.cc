// network/networks.cc — a scenario's [[network]] and [[background]] tables, read and checked
// (network/networks.h).
#include "network/networks.h"

#include <fmt/format.h>

#include <Eigen/Dense>
#include <algorithm>
#include <sstream>

#include "network/merged_run.h"
#include "network/network.h"
#include "network/worker.h"

namespace ncosim::network {

using config::Key;

const config::Keys& network_keys() {
  static const config::Keys keys{
      Key::string("name").help("unique among networks; a [[link]] of kind network names it"),
      Key::string("kind").help("the network kind (below)"),
      Key::string("sink_vehicle")
          .optional("none: the kind's fixed sink_position")
          .help("a [sumo] vehicle the sink (the estimators' node) rides, for kinds with "
                "positions: its position is the vehicle's (x, y, z = 1.5 m) at every period, out "
                "of everyone's range while the vehicle is not in the traffic"),
  };
  return keys;
}

const config::Keys& background_keys() {
  static const config::Keys keys{
      Key::string("network").help("the [[network]] the nodes are nodes of (its name)"),
      Key::integer("nodes")
          .range(1, 10000)
          .optional("1, or the number of positions")
          .help("how many nodes of this traffic"),
      Key::number("rate")
          .above(0.0)
          .max(1e7)
          .or_words({"saturated"})
          .says("a rate in (0, 1e7] packets/s or \"saturated\"")
          .unit("packets/s")
          .help("each node's own traffic: a Poisson process of this many packets per second (> 0), "
                "or \"saturated\": a packet always waiting (a new one the moment the stack is "
                "done with one)"),
      Key::integer("bytes").range(1, 1500).or_default(32).unit("bytes").help(
          "payload of each packet (at most the network's largest payload)"),
      Key::numbers("position")
          .optional("[0, 0, 0]")
          .entries(3)
          .unit("m")
          .help("[x, y, z] of every node, for the network kinds with positions"),
      Key::matrix("positions")
          .optional("none: every node at `position`")
          .columns(3)
          .unit("m")
          .help("[[x, y, z], ...]: one row per node (instead of position)"),
      Key::string("vehicles")
          .optional("none: fixed positions")
          .help("\"all\": one node riding each vehicle of the [sumo] traffic (every vehicle its "
                "route files define by id), moved at every period's start; a vehicle not in the "
                "traffic is out of everyone's range (instead of nodes, position, positions)"),
  };
  return keys;
}

namespace {

// The index of the [[network]] named by key `key` of `t` (an error listing the names otherwise).
int network_named(const config::Table& t, std::string_view key, const std::string& name,
                  const std::vector<NetworkEntry>& networks) {
  for (std::size_t n = 0; n < networks.size(); ++n) {
    if (networks[n].name == name) return static_cast<int>(n);
  }
  std::string names;
  for (const auto& n : networks)
    names += (names.empty() ? "" : ", ") + fmt::format("\"{}\"", n.name);
  t.fail(key, fmt::format("expected the name of a [[network]] ({}), got \"{}\"",
                          names.empty() ? "the scenario has none" : names, name));
}

// A background table's traffic: rate (packets/s, a Poisson process) or "saturated".
void read_traffic(const config::Table& t, Sender& s) {
  if (!t.has("rate")) t.fail("rate", "expected a rate in packets/s or \"saturated\", got nothing");
  if (t.is_string("rate")) {
    const std::string v = t.string("rate");
    if (v != "saturated")
      t.fail("rate", fmt::format("expected a rate in packets/s or \"saturated\", got \"{}\"", v));
    s.traffic = Traffic::kSaturated;
    return;
  }
  s.traffic = Traffic::kPoisson;
  s.rate = t.number("rate");
  if (!(s.rate > 0.0 && s.rate <= 1e7))
    t.fail("rate",
           fmt::format("expected a rate in (0, 1e7] packets/s or \"saturated\", got {}", s.rate));
}

// A background table with `vehicles = "all"`: a node on every vehicle of the [sumo] traffic.
void read_vehicle_nodes(const config::Table& t, const config::KeyReader& r, const NetworkEntry& n,
                        Sender s, models::MobilitySource* mobility, std::vector<Sender>& out) {
  if (r.string("vehicles") != "all")
    t.fail("vehicles", fmt::format("expected \"all\", got \"{}\"", r.string("vehicles")));
  for (const char* key : {"nodes", "position", "positions"}) {
    if (t.has(key)) t.fail(key, fmt::format("expected no {} with vehicles", key));
  }
  if (!n.design->has_positions()) {
    t.fail("vehicles",
           fmt::format("expected no vehicles: network \"{}\" (kind {}) has no positions", n.name,
                       n.kind));
  }
  if (mobility == nullptr)
    t.fail("vehicles",
           "expected a [sumo] table (the vehicles' mobility) for nodes that ride "
           "vehicles");
  for (const int v : mobility->every_vehicle(t, "vehicles")) {
    s.vehicle = v;
    s.z = kAway;  // until its vehicle is placed, at the run's first period
    out.push_back(s);
  }
  t.finish();
}

// A background table's fixed nodes: `nodes` at `position`, or one per row of `positions`.
void read_fixed_nodes(const config::Table& t, const config::KeyReader& r, Sender s,
                      std::vector<Sender>& out) {
  Eigen::MatrixXd at = Eigen::MatrixXd::Zero(1, 3);
  if (t.has("position")) {
    const std::array<double, 3> p = read_xyz(t, r, "position");
    for (int i = 0; i < 3; ++i) at(0, i) = p[static_cast<std::size_t>(i)];
  }
  if (t.has("positions")) {
    at = r.matrix("positions");
    if (at.cols() != 3)
      t.fail("positions",
             fmt::format("expected rows [x, y, z] (m), got rows of {} numbers", at.cols()));
  }
  const std::int64_t nodes = r.opt_integer("nodes").value_or(t.has("positions") ? at.rows() : 1);
  if (t.has("positions") && nodes != at.rows())
    t.fail("nodes",
           fmt::format("expected as many nodes as positions ({}), got {}", at.rows(), nodes));
  for (std::int64_t i = 0; i < nodes; ++i) {
    const Eigen::Index row = t.has("positions") ? static_cast<Eigen::Index>(i) : 0;
    s.x = at(row, 0);
    s.y = at(row, 1);
    s.z = at(row, 2);
    out.push_back(s);
  }
  t.finish();
}

}  // namespace

void Networks::read(const config::Table& root, const NetworkRegistry& kinds,
                    models::MobilitySource* mobility) {
  for (const config::Table& t : root.tables("network")) {
    NetworkEntry e;
    const config::KeyReader common(t, network_keys());
    e.name = common.string("name");
    if (std::any_of(entries_.begin(), entries_.end(),
                    [&](const NetworkEntry& n) { return n.name == e.name; })) {
      t.fail("name", fmt::format("expected a unique network name, got \"{}\" twice", e.name));
    }
    const auto& k = kinds.lookup(t, "kind", "");
    e.kind = k.name;
    e.design = k.factory(t);
    if (common.has("sink_vehicle")) {
      if (!e.design->has_positions()) {
        t.fail("sink_vehicle",
               fmt::format("expected no sink_vehicle: network kind {} has no positions", e.kind));
      }
      if (mobility == nullptr)
        t.fail("sink_vehicle",
               "expected a [sumo] table (the vehicles' mobility) for a sink that "
               "rides a vehicle");
      if (t.has("sink_position"))
        t.fail("sink_vehicle", "expected `sink_vehicle` or `sink_position`, not both");
      e.sink_vehicle = mobility->vehicle(t, "sink_vehicle");
    }
    t.finish();
    std::ostringstream text;
    text << t.raw();
    e.table = text.str();
    if (e.design->engine().needs_own_process() && !pool_) pool_ = std::make_shared<WorkerPool>();
    entries_.push_back(std::move(e));
  }
  for (const config::Table& t : root.tables("background")) {
    const config::KeyReader r(t, background_keys());
    Sender s;
    s.network = network_named(t, "network", r.string("network"), entries_);
    const NetworkEntry& n = entries_[static_cast<std::size_t>(s.network)];
    read_traffic(t, s);
    s.bytes = static_cast<std::uint32_t>(r.integer("bytes"));
    if (s.bytes > n.design->max_payload()) {
      t.fail("bytes", fmt::format("expected at most {} bytes, the largest payload of network "
                                  "\"{}\" (kind {}), got {}",
                                  n.design->max_payload(), n.name, n.kind, s.bytes));
    }
    for (const char* key : {"position", "positions"}) {
      if (t.has(key) && !n.design->has_positions())
        t.fail(key, fmt::format("expected no position: network \"{}\" (kind {}) has none", n.name,
                                n.kind));
    }
    if (t.has("position") && t.has("positions"))
      t.fail("positions", "expected either position or positions, got both");
    if (r.has("vehicles")) {
      read_vehicle_nodes(t, r, n, s, mobility, background_);
    } else {
      read_fixed_nodes(t, r, s, background_);
    }
  }
}

void Networks::drop_doubled_riders(const std::vector<const models::NetworkAttachment*>& links) {
  std::vector<std::pair<int, int>> riders;  // (network, vehicle) of the links' nodes and sinks
  for (const models::NetworkAttachment* a : links) {
    if (a != nullptr && a->vehicle >= 0) riders.emplace_back(a->network, a->vehicle);
  }
  for (std::size_t n = 0; n < entries_.size(); ++n) {
    if (entries_[n].sink_vehicle >= 0)
      riders.emplace_back(static_cast<int>(n), entries_[n].sink_vehicle);
  }
  std::erase_if(background_, [&](const Sender& s) {
    return s.vehicle >= 0 &&
           std::find(riders.begin(), riders.end(), std::pair{s.network, s.vehicle}) != riders.end();
  });
}

namespace {

// A link that is a node of network `n`: its payload, its position's key and its range.
void check_node(const config::Table& t, const models::NetworkAttachment& a, const NetworkEntry& n) {
  if (a.bytes > n.design->max_payload()) {
    t.fail("bytes", fmt::format("expected at most {} bytes, the largest payload of network \"{}\" "
                                "(kind {}), got {}",
                                n.design->max_payload(), n.name, n.kind, a.bytes));
  }
  for (const std::string key : {"position", "vehicle"}) {
    if (t.has(key) && !n.design->has_positions()) {
      t.fail(key, fmt::format("expected no {}: network \"{}\" (kind {}) has {}", key, n.name,
                              n.kind, key == "position" ? "none" : "no positions"));
    }
  }
  // A sender the sink cannot hear loses every packet: a mistake, not a network to study (nodes
  // that ride SUMO vehicles move in and out of range: no check).
  if (a.vehicle >= 0 || n.sink_vehicle >= 0) return;
  const double at[3] = {a.x, a.y, a.z};
  const auto r = n.design->reach(at);
  if (r && !(r->received_dbm >= r->threshold_dbm)) {
    t.fail("position",
           fmt::format("expected a node within range of network \"{}\"'s sink (kind {}): at {:.4g} "
                       "m the sink receives {:.2f} dBm from it, below the {:.2f} dBm it needs ({})",
                       n.name, n.kind, r->distance_m, r->received_dbm, r->threshold_dbm,
                       r->threshold_why));
  }
}

}  // namespace

void Networks::check(const config::Table& root,
                     const std::vector<const models::NetworkAttachment*>& links,
                     const std::vector<char>& used) const {
  const auto tables = root.tables("network");
  const auto link_tables = root.tables("link");
  std::vector<char> carries(entries_.size(), 0);  // some sensor or actuator sends over it
  for (std::size_t l = 0; l < links.size(); ++l) {
    const models::NetworkAttachment* a = links[l];
    if (a == nullptr) continue;
    check_node(link_tables[l], *a, entries_[static_cast<std::size_t>(a->network)]);
    if (used[l] != 0) carries[static_cast<std::size_t>(a->network)] = 1;
  }
  for (std::size_t n = 0; n < entries_.size(); ++n) {
    if (carries[n] == 0) {
      tables[n].fail("name", fmt::format("expected a network that a sensor's or an actuator's "
                                         "link is a node of, got \"{}\", which no [[sensor]] "
                                         "or [[actuator]] sends over",
                                         entries_[n].name));
    }
  }
}

std::vector<std::string> Networks::names() const {
  std::vector<std::string> out;
  for (const auto& n : entries_) out.push_back(n.name);
  return out;
}

bool Networks::needs_own_process() const {
  return std::any_of(entries_.begin(), entries_.end(),
                     [](const NetworkEntry& n) { return n.design->engine().needs_own_process(); });
}

std::unique_ptr<NetworkRun> Networks::start(std::vector<Sender> senders, std::uint64_t seed,
                                            std::uint64_t run) const {
  senders.insert(senders.end(), background_.begin(), background_.end());
  std::vector<const NetworkDesign*> designs;
  for (const auto& n : entries_) designs.push_back(n.design.get());
  return start_merged(designs, senders,
                      [&](const NetworkEngine& engine, const std::vector<std::size_t>& own,
                          const std::vector<Sender>& local) -> std::unique_ptr<NetworkRun> {
                        if (engine.needs_own_process()) {
                          std::vector<WorkerNetwork> tables;
                          for (const std::size_t n : own)
                            tables.push_back(WorkerNetwork{entries_[n].kind, entries_[n].table});
                          return pool_->start(tables, local, seed, run);
                        }
                        std::vector<const NetworkDesign*> mine;
                        for (const std::size_t n : own) mine.push_back(designs[n]);
                        return engine.start(mine, local, seed, run);
                      });
}

}  // namespace ncosim::network
