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

#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "config/registry.h"
#include "kernel/time.h"
#include "models/link_factory.h"

namespace ncosim::network {

class World;  // one run's ns-3 simulation (network/world.h; only in builds with ns-3)

// What happened to one packet: delivered to the sink at `time`, or dropped by the stack.
// kNoAck: the MAC gave up after its retransmissions although the sink could hear the sender
// (collisions or noise); kOutOfRange: the same, from a sender whose signal reaches the sink below
// what its receiver can receive (NetworkDesign::reach), so that no retransmission could help.
enum class Drop : std::uint8_t { kNone, kQueue, kChannelAccess, kNoAck, kOutOfRange };
inline constexpr std::size_t kDropCauses = 5;  // the values of Drop
struct Fate {
  int sender = 0;            // the sender's index in the session (Session::start)
  std::uint64_t id = 0;      // the id given to Session::send
  kernel::SimTime time = 0;  // when the stack delivered or dropped it (ns)
  Drop drop = Drop::kNone;
};

// What one sender's stack did in a run (Session::counters): each kind counts what its MAC exposes.
struct MacCounters {
  std::uint64_t delivered = 0;              // packets the sink received
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
  // Whether it builds actuator links (Sender::downlink): csma and lr_wpan do.
  virtual bool carries_actuators() const { return false; }
  // The largest payload of one packet (bytes), at most 1500.
  virtual std::uint32_t max_payload() const { return 1500; }
  // For a kind with positions: how a sender at `position` (m) reaches the sink when alone on the
  // channel; nullopt for a kind without positions. The scenario reader refuses a sender out of
  // range (sim/scenario/scenario_sections.cc check_networks).
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
};

using NetworkRegistry = config::Registry<std::shared_ptr<const NetworkDesign>>;
void register_networks(NetworkRegistry& registry);
// The `network` link kind (network/network_link.h): a [[link]] that is a node of a [[network]].
void register_network_links(models::LinkRegistry& registry);

// The seed of ns-3's generator for campaign seed `seed` (a run is its sub-stream): in 1..2^32 -
// 210.
std::uint32_t ns3_seed(std::uint64_t seed);

// The [x, y, z] (m) of the numbers key `key` of `t` (read through `r`): exit 2 unless it holds
// exactly three numbers.
std::array<double, 3> read_xyz(const config::Table& t, const config::KeyReader& r,
                               std::string_view key);

// The keys every radio kind (lr_wpan, wifi) declares alike: `sink_position` ([x, y, z] m, default
// the origin) and `path_loss_exponent` (log-distance, default 3). Each kind declares its own
// `reference_loss` (its carrier's free space at 1 m).
config::Key sink_position_key();
config::Key path_loss_exponent_key();

// True when this build has ns-3 (NCOSIM_HAVE_NS3): else the network kinds' readers refuse.
bool have_ns3();
// The message of a build without ns-3 ("this ncosim was built without ns-3 ...").
std::string without_ns3_message();

// Where a sender's packets come from. kSensor: the run hands them over (Session::send) and gets
// their fates. A background node ([[background]]) makes its own traffic inside the session, whose
// packets contend with the sensors' but whose fates are only counted (Session::counters):
// kPoisson, a Poisson process of `rate` packets/s; kSaturated, a packet always waiting (a new one
// is handed to the device as soon as one of its packets is delivered or dropped).
enum class Traffic : std::uint8_t { kSensor, kPoisson, kSaturated };

// A sender: a [[link]] of kind `network` or a background node, the network it is attached to and
// its payload.
// A `downlink` sender is an actuator's link: its packets go the other way, from the controller
// (the sink's side) to the node at its position (the actuator). Every kind builds it as two nodes
// after the sensors' ones: a transmitter of its own at the sink's position (the controller's
// radio; it does not share the sink's device, so the sink still receives while it sends) and the
// actuator's node, which receives.
struct Sender {
  int network = 0;                   // index into the session's networks
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
  // Sensor `sender` hands packet `id` to its network at time t (t >= every earlier advance_to).
  virtual void send(int sender, std::uint64_t id, kernel::SimTime t) = 0;
  // Runs ns-3 through every event at times <= t, appending what happened to packets to `fates`
  // in the order ns-3 processed it.
  virtual void advance_to(kernel::SimTime t, std::vector<Fate>& fates) = 0;
  // Sender `sender`'s node (or the sink of network `network`) is at (x, y, z) from time t on
  // (t >= every earlier advance_to), for a node that rides a SUMO vehicle. Earlier sends and
  // moves at the same t take effect first.
  virtual void move_sender(int sender, double x, double y, double z, kernel::SimTime t) = 0;
  virtual void move_sink(int network, double x, double y, double z, kernel::SimTime t) = 0;
  // What sender `sender`'s stack did so far in this run.
  virtual MacCounters counters(int sender) const = 0;
};

}  // namespace ncosim::network
