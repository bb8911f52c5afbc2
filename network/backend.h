// network/backend.h — a packet network as the run engine sees it, and what a network backend
// implements: a kind of [[network]] table (NetworkDesign, read by its registry entry) simulated by
// an engine (NetworkEngine) one Monte Carlo run at a time (NetworkRun). ns-3 is one backend
// (network/ns3/); a backend of your own registers its kinds through sim::Registries::networks
// (docs/extending.md; examples/tdma_bus is one, written against this header alone).
//
// The run engine's side of the contract, per run: it hands each sensor's packet to its node
// (send), moves the nodes that ride vehicles (move_sender, move_sink), and at every period
// boundary asks the network to run through that instant (advance_to) and say what happened to
// each packet (the fates); a packet delivered in ((k - 1) T, k T] is used by the estimators at
// k T. At the end it asks what each node's MAC did (counters). An engine that cannot run two
// simulations in one process (ns-3) says so (NetworkEngine::needs_own_process): every run of it
// then lives in a worker process of its own, driven through this same interface over a socket,
// while the run engine and the estimators stay in the caller's threads.
//
// Self-contained: the standard library and ncosim's registry of kinds (config/registry.h) only.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "config/registry.h"

namespace ncosim::network {

// Simulated time in integer nanoseconds since the run's start (the kernel's clock, kernel/time.h).
using Nanoseconds = std::int64_t;

// What happened to one packet: delivered to its destination at `time`, or dropped by the stack.
// kNoAck: the MAC gave up after its retransmissions although the destination could hear the
// sender (collisions or noise); kOutOfRange: the same, from a sender whose signal reaches the
// destination below what its receiver can receive (NetworkDesign::reach), so that no
// retransmission could help.
enum class Drop : std::uint8_t { kNone, kQueue, kChannelAccess, kNoAck, kOutOfRange };
inline constexpr std::size_t kDropCauses = 5;  // the values of Drop
struct Fate {
  int sender = 0;        // the sender's index in the run (NetworkEngine::start's `senders`)
  std::uint64_t id = 0;  // the id given to NetworkRun::send
  Nanoseconds time = 0;  // when the stack delivered or dropped it
  Drop drop = Drop::kNone;
};

// What one sender's stack did in a run (NetworkRun::counters): each kind counts what its MAC
// exposes.
struct MacCounters {
  std::uint64_t delivered = 0;              // packets the destination received
  std::uint64_t attempts = 0;               // frames put on the air, retransmissions included
  std::uint64_t retries = 0;                // of which retransmissions
  std::uint64_t dropped[kDropCauses] = {};  // packets lost, by cause (index: Drop; kNone unused)
  std::int64_t busy_ns = -1;                // time the sender sensed the channel busy (-1: the
                                            // kind does not expose it)
};

// Where a sender's packets come from. kSensor: the run hands them over (NetworkRun::send) and
// gets their fates. A background node ([[background]]) makes its own traffic inside the run,
// whose packets contend with the sensors' but whose fates are only counted (counters):
// kPoisson, a Poisson process of `rate` packets/s; kSaturated, a packet always waiting (a new one
// is handed to the device as soon as one of its packets is delivered or dropped).
enum class Traffic : std::uint8_t { kSensor, kPoisson, kSaturated };

// A sender: a [[link]] of kind `network` or a background node, the network it is attached to and
// its payload. A `downlink` sender is an actuator's link: its packets go the other way, from the
// controller (the sink's side) to the node at its position (the actuator).
struct Sender {
  int network = 0;                   // index into the engine's networks (NetworkEngine::start)
  std::uint32_t bytes = 0;           // payload bytes of each packet
  double x = 0.0, y = 0.0, z = 0.0;  // position (m), for the kinds that have positions
  Traffic traffic = Traffic::kSensor;
  int vehicle = -1;       // a background node riding a [sumo] vehicle: its index in the mobility
  double rate = 0.0;      // kPoisson: mean packets per second
  bool downlink = false;  // an actuator's link (controller -> actuator)
};

// Where a node that is not in the network (a SUMO vehicle before its departure or after its
// arrival) is put: so far above every other node that it receives nothing and is received by
// no one, whatever the path loss.
inline constexpr double kAway = 1e9;  // m (z)

// One Monte Carlo run of the networks of one engine. Calls come from one thread, with times that
// never decrease: sends and moves at t are made before advance_to(t). Failure: a run whose
// simulation cannot go on throws (EngineFailure, network/networks.h, when its process died).
class NetworkRun {
 public:
  virtual ~NetworkRun() = default;
  // Sensor `sender` hands packet `id` to its network at time t (t >= every earlier advance_to).
  virtual void send(int sender, std::uint64_t id, Nanoseconds t) = 0;
  // Runs the networks through every event at times <= t, appending what happened to the sensors'
  // packets to `fates` in the order the simulation decided it.
  virtual void advance_to(Nanoseconds t, std::vector<Fate>& fates) = 0;
  // Sender `sender`'s node (or the sink of network `network`) is at (x, y, z) from time t on
  // (t >= every earlier advance_to), for a node that rides a SUMO vehicle. Earlier sends and
  // moves at the same t take effect first.
  virtual void move_sender(int sender, double x, double y, double z, Nanoseconds t) = 0;
  virtual void move_sink(int network, double x, double y, double z, Nanoseconds t) = 0;
  // What sender `sender`'s stack did so far in this run.
  virtual MacCounters counters(int sender) const = 0;
};

class NetworkDesign;

// A simulator of network kinds. One NetworkRun of an engine holds every network of the scenario
// that the engine simulates (ns-3: one simulator for them all).
class NetworkEngine {
 public:
  virtual ~NetworkEngine() = default;
  // For messages: "ns-3".
  virtual std::string name() const = 0;
  // True when two runs cannot share a process (ns-3 has one simulator per process and keeps state
  // across its simulations): every run then gets a worker process of its own, which reads the
  // networks' tables again with the same registry (the ncosim executable, or a program of yours
  // whose main calls run_cli).
  virtual bool needs_own_process() const { return false; }
  // Run `run` of `networks` (this engine's, in scenario order) with `senders` (Sender::network
  // indexes `networks`): the links' senders first, then the background nodes. Its random numbers
  // come from (seed, run) alone, so that a run is the same whatever process or thread runs it.
  virtual std::unique_ptr<NetworkRun> start(const std::vector<const NetworkDesign*>& networks,
                                            const std::vector<Sender>& senders, std::uint64_t seed,
                                            std::uint64_t run) const = 0;
};

// One [[network]] table, read by its kind's registry entry.
class NetworkDesign {
 public:
  virtual ~NetworkDesign() = default;
  // The engine that simulates it (one object for every network it simulates).
  virtual const NetworkEngine& engine() const = 0;
  // Whether its nodes have positions (a [[link]] `position` on a network without is refused).
  virtual bool has_positions() const { return false; }
  // Whether it carries actuators' links (Sender::downlink).
  virtual bool carries_actuators() const { return false; }
  // The largest payload of one packet (bytes), at most 1500.
  virtual std::uint32_t max_payload() const { return 1500; }
  // For a kind with positions: how a sender at `position` (m) reaches the sink when alone on the
  // channel; nullopt when it cannot say (no positions, or fading). The scenario reader refuses a
  // fixed sender out of range.
  struct Reach {
    double distance_m = 0.0;     // from the sink
    double received_dbm = 0.0;   // the power the sink receives from it
    double threshold_dbm = 0.0;  // the least power at which the sink's receiver can receive
    std::string threshold_why;   // where the threshold comes from, for the message
  };
  virtual std::optional<Reach> reach(const double (&position)[3]) const {
    (void)position;
    return std::nullopt;
  }
  // What one run of this network holds in its worker's memory, for the estimate the scenario
  // reader checks against --max-memory before t = 0: every node (the sink, the links' senders, the
  // background nodes) and every packet waiting in a node's queue. Packets made beyond what the
  // channel surely carries (`carried_per_second`, a lower bound) wait, up to `queue_packets` per
  // node. The defaults are generous; a kind measures its own.
  struct Footprint {
    double node_bytes = 256e3;
    double packet_bytes = 8e3;
    double queue_packets = 1e300;  // no bound
    double carried_per_second = 10.0;
  };
  virtual Footprint footprint() const { return {}; }
};

// The registry of network kinds: a kind's factory reads its [[network]] table (its own keys; the
// section's name, kind and sink_vehicle are read by ncosim).
using NetworkRegistry = config::Registry<std::shared_ptr<const NetworkDesign>>;

}  // namespace ncosim::network
