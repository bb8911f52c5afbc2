// network/network.h — packet-level networks: a scenario's [[network]] tables, simulated by ns-3
// in the run's own process, with ncosim's kernel as the master clock.
//
// Every [[link]] of kind `network` is a node of the network it names; every packet a sensor hands
// to such a link is sent by that node to the network's sink (the estimators' node) through ns-3's
// protocol stack, so the packets of all the senders of one network contend. The run advances ns-3
// in lockstep (Session::advance_to): at the start of control period k, after the period's sends,
// ns-3 processes every event up to and including t = k T; each packet received in
// ((k - 1) T, k T] becomes an arrival at k T, before that period's estimator updates (the
// contract of the kernel: arrivals between two periods are used at the next update; an estimator
// sees the true delay from the sample's time stamp). ns-3 is optional: a build without it reads
// and documents every network kind but refuses a scenario that uses one, naming what to install.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "config/registry.h"
#include "kernel/time.h"
#include "models/link_factory.h"

namespace ncosim::network {

class World;  // one run's ns-3 simulation (network/world.h; only in builds with ns-3)

// What happened to one packet: delivered to the sink at `time`, or dropped by the stack.
// kNoAck: the MAC gave up after its retransmissions (collisions, fading or range).
enum class Drop : std::uint8_t { kNone, kQueue, kChannelAccess, kNoAck };
inline constexpr std::size_t kDropCauses = 4;  // the values of Drop
struct Fate {
  int sender = 0;            // the sender's index in the session (Session::start)
  std::uint64_t id = 0;      // the id given to Session::send
  kernel::SimTime time = 0;  // when the stack delivered or dropped it (ns)
  Drop drop = Drop::kNone;
};

// What one sender's stack did in a run (Session::counters): each kind counts what its MAC exposes.
struct MacCounters {
  std::uint64_t attempts = 0;               // frames put on the air, retransmissions included
  std::uint64_t retries = 0;                // of which retransmissions
  std::uint64_t dropped[kDropCauses] = {};  // packets lost, by cause (index: Drop; kNone unused)
  std::int64_t busy_ns = -1;                // time the sender sensed the channel busy (-1: the
                                            // kind does not expose it)
};

// One [[network]] table, read: what builds its ns-3 part in every run.
class NetworkDesign {
 public:
  virtual ~NetworkDesign() = default;
  // Adds this network to the run's world: the sink, then one node per sender (`senders` are the
  // world's sender indices attached to this network, in scenario order), then the transmitters of
  // the downlink senders (Sender::downlink) at the sink's position, in the same order.
  virtual void build(World& world, const std::vector<int>& senders) const = 0;
  // Whether its nodes have positions (a [[link]] `position` on a network without is refused).
  virtual bool has_positions() const { return false; }
  // The largest payload of one packet (bytes), at most 1500.
  virtual std::uint32_t max_payload() const { return 1500; }
};

using NetworkRegistry = config::Registry<std::shared_ptr<const NetworkDesign>>;
void register_networks(NetworkRegistry& registry);
// The `network` link kind (network/network_link.h): a [[link]] that is a node of a [[network]].
void register_network_links(models::LinkRegistry& registry);

// The seed of ns-3's generator for campaign seed `seed` (a run is its sub-stream): in 1..2^32 -
// 210.
std::uint32_t ns3_seed(std::uint64_t seed);

// True when this build has ns-3 (NCOSIM_HAVE_NS3): else the network kinds' readers refuse.
bool have_ns3();
// The message of a build without ns-3 ("this ncosim was built without ns-3 ...").
std::string without_ns3_message();

// A sender: the [[link]] of kind `network` it is, the network it is attached to and its payload.
// A `downlink` sender is an actuator's link: its packets go the other way, from the controller
// (the sink's side) to the node at its position (the actuator). Every kind builds it as two nodes
// after the sensors' ones: a transmitter of its own at the sink's position (the controller's
// radio; it does not share the sink's device, so the sink still receives while it sends) and the
// actuator's node, which receives.
struct Sender {
  int network = 0;                   // index into the session's networks
  std::uint32_t bytes = 0;           // payload bytes of each packet
  double x = 0.0, y = 0.0, z = 0.0;  // position (m), for the kinds that have positions
  bool downlink = false;             // an actuator's link (controller -> actuator)
};

// One run's networks in ns-3. ns-3 has one simulator per process: a session holds it (other
// threads of the process that start a session wait for it to end).
class Session {
 public:
  // Builds the networks (`designs`, in scenario order) with their senders, ns-3's random streams
  // seeded from (seed, run).
  static std::unique_ptr<Session> start(
      const std::vector<std::shared_ptr<const NetworkDesign>>& designs,
      const std::vector<Sender>& senders, std::uint64_t seed, std::uint64_t run);
  virtual ~Session() = default;
  // Sender `sender` hands packet `id` to its network at time t (t >= every earlier advance_to).
  virtual void send(int sender, std::uint64_t id, kernel::SimTime t) = 0;
  // Runs ns-3 through every event at times <= t, appending what happened to packets to `fates`
  // in the order ns-3 processed it.
  virtual void advance_to(kernel::SimTime t, std::vector<Fate>& fates) = 0;
  // What sender `sender`'s stack did so far in this run.
  virtual MacCounters counters(int sender) const = 0;
};

}  // namespace ncosim::network
