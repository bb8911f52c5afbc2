// network/networks.h — a scenario's packet networks: its [[network]] and [[background]] tables
// read (each [[network]] by its kind's registry entry, network/backend.h), checked against the
// links that are their nodes, and started once per Monte Carlo run. A run's networks are one
// NetworkRun whatever their engines: the networks of an engine that needs a process of its own
// (ns-3) run in a worker process (network/worker.h), the others in the caller's thread, and the
// run engine (sim/run/) sees one interface.
#pragma once

#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "config/config.h"
#include "config/keys.h"
#include "models/link.h"
#include "models/mobility.h"
#include "network/backend.h"

namespace ncosim::network {

// A run whose network simulation died (its worker process ended abnormally: a crash inside ns-3,
// NS_FATAL_ERROR, NS_ASSERT, a signal): that run is lost, the campaign goes on without it.
struct EngineFailure : std::runtime_error {
  using std::runtime_error::runtime_error;
};

class WorkerPool;  // network/worker.h

// One [[network]] table, read.
struct NetworkEntry {
  std::string name;
  std::string kind;
  std::shared_ptr<const NetworkDesign> design;
  int sink_vehicle = -1;  // the [sumo] vehicle the sink rides (index in the mobility), or -1
  std::string table;      // the table as TOML text: what a worker process reads again
};

// The keys of [[network]] beside its kind's (name, kind, sink_vehicle) and of [[background]].
const config::Keys& network_keys();
const config::Keys& background_keys();

class Networks {
 public:
  // Reads [[network]] (kinds from `kinds`), then [[background]] (after the networks it names) of
  // `root`; `mobility` (null without [sumo]) resolves the vehicles nodes ride. Throws
  // config::ScenarioError at the key at fault.
  void read(const config::Table& root, const NetworkRegistry& kinds,
            models::MobilitySource* mobility);
  // A vehicle whose node on a network is a link's or the sink has no background node there too
  // ([[background]] vehicles = "all" names every vehicle). `links[l]`: [[link]] l's attachment
  // (nullptr: not a node of a network).
  void drop_doubled_riders(const std::vector<const models::NetworkAttachment*>& links);
  // Once the links, sensors and actuators are read: each node's payload, position and range, and
  // that a sensor or an actuator sends over every network (`used[l]`: some sensor or actuator
  // sends over link l). Throws config::ScenarioError at the [[link]] or [[network]] at fault.
  void check(const config::Table& root, const std::vector<const models::NetworkAttachment*>& links,
             const std::vector<char>& used) const;

  bool empty() const { return entries_.empty(); }
  std::size_t size() const { return entries_.size(); }
  const NetworkEntry& operator[](std::size_t n) const { return entries_[n]; }
  std::vector<NetworkEntry>::const_iterator begin() const { return entries_.begin(); }
  std::vector<NetworkEntry>::const_iterator end() const { return entries_.end(); }
  // Every background node, table by table, after the links' senders in each run.
  const std::vector<Sender>& background() const { return background_; }
  std::vector<std::string> names() const;

  // Whether a run of these networks may die with its worker process (EngineFailure).
  bool needs_own_process() const;
  // Run `run`: `senders` are the links' (in link order; Sender::network indexes this scenario's
  // networks), followed here by the background nodes; the fates' and counters' sender indices
  // are the same.
  std::unique_ptr<NetworkRun> start(std::vector<Sender> senders, std::uint64_t seed,
                                    std::uint64_t run) const;

 private:
  std::vector<NetworkEntry> entries_;
  std::vector<Sender> background_;
  // The worker processes of the engines that need their own (null: none does).
  std::shared_ptr<WorkerPool> pool_;
};

// One run of `networks` in this process, whatever their engines need (a worker process, the
// tests and the benchmarks): the networks of each engine in one NetworkRun of it, merged.
std::unique_ptr<NetworkRun> start_here(const std::vector<const NetworkDesign*>& networks,
                                       const std::vector<Sender>& senders, std::uint64_t seed,
                                       std::uint64_t run);

}  // namespace ncosim::network
