// network/ns3/world.h — one run's ns-3 simulation (builds with ns-3 only): the nodes, their
// devices, where each sender's packets go, and what the stack did to them. The network kinds'
// build() add their nodes and devices here (network/ns3/ns3_network.h). Private to the ns-3
// backend.
#pragma once

#include <ns3/address.h>
#include <ns3/mobility-model.h>
#include <ns3/net-device-container.h>
#include <ns3/net-device.h>
#include <ns3/node-container.h>
#include <ns3/packet.h>
#include <ns3/ptr.h>
#include <ns3/random-variable-stream.h>

#include <array>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <unordered_map>
#include <vector>

#include "network/ns3/ns3_network.h"

namespace ncosim::network {

class World {
 public:
  explicit World(std::vector<Sender> senders);
  // The network being built: the sink's device (packets addressed to it are deliveries) and each
  // sender's device (it sends to `sink`, the sink device's address). `confirms`: the kind reports
  // the end of each of the sender's packets through confirmed(), in the order they were sent (a
  // MAC that handles one frame at a time, e.g. IEEE 802.15.4).
  void attach_sink(const ns3::Ptr<ns3::NetDevice>& device);
  void attach_sender(int sender, const ns3::Ptr<ns3::NetDevice>& device, const ns3::Address& sink,
                     bool confirms = false);
  // The layout every kind builds (network.h): node 0 is the sink, nodes 1..n the nodes of
  // `senders` in order, then one transmitter beside the sink per downlink sender (an actuator's
  // link), in the same order. These nodes, created:
  ns3::NodeContainer create_nodes(const std::vector<int>& senders) const;
  // Node `node`'s position in that layout, `sink` (m) for the sink and the transmitters, set up for
  // the session's moves (mobile_sink, mobile_sender).
  ns3::Ptr<ns3::MobilityModel> place(std::uint32_t node, const std::vector<int>& senders,
                                     const std::array<double, 3>& sink);
  // Attaches the sink and every sender to its device of `devices` (one per node, in that layout):
  // a sender sends to the sink; for a downlink sender the transmitter sends and the sender's own
  // node receives. Then calls `connect(sender, device)` for the kind's trace sources.
  using Connect = std::function<void(int sender, const ns3::Ptr<ns3::NetDevice>& device)>;
  void attach_all(const ns3::NetDeviceContainer& devices, const std::vector<int>& senders,
                  bool confirms, const Connect& connect);
  // Connects the drop trace source `trace` of a sender's device: a packet it fires for is lost
  // for `cause`.
  void connect_drop(const ns3::Ptr<ns3::NetDevice>& device, const char* trace, Drop cause);
  void dropped(Drop cause, const ns3::Ptr<const ns3::Packet>& p);
  // The sender's MAC is done with its oldest packet: sent (kNone: its delivery is the sink's
  // reception) or dropped for `drop`.
  void confirmed(int sender, Drop drop);
  // The kinds count what their MAC does: sender `s` put a frame on the air (`retry`: a
  // retransmission), or its PHY sensed the channel busy for `ns` more nanoseconds.
  void attempt(int s, bool retry) {
    MacCounters& c = ports_[static_cast<std::size_t>(s)].counters;
    ++c.attempts;
    if (retry) ++c.retries;
  }
  // The same for a frame `p` the sender's MAC puts on the air: a retransmission when it carries the
  // same packet as the sender's previous attempt.
  void attempt_packet(int s, const ns3::Ptr<const ns3::Packet>& p);
  void busy(int s, std::int64_t ns) {
    MacCounters& c = ports_[static_cast<std::size_t>(s)].counters;
    c.busy_ns = (c.busy_ns < 0 ? 0 : c.busy_ns) + ns;
  }
  const MacCounters& counters(int s) const { return ports_[static_cast<std::size_t>(s)].counters; }
  // The mobility model of sender `s`'s node, and of the sink of the network being built: the
  // run moves them (NetworkRun::move_sender, move_sink) for nodes that ride SUMO vehicles.
  void mobile_sender(int s, const ns3::Ptr<ns3::MobilityModel>& m) {
    ports_[static_cast<std::size_t>(s)].mobility = m;
  }
  void mobile_sink(const ns3::Ptr<ns3::MobilityModel>& m) {
    if (sinks_.size() <= static_cast<std::size_t>(building_)) sinks_.resize(building_ + 1);
    sinks_[static_cast<std::size_t>(building_)] = m;
  }
  void building(int network) { building_ = network; }
  ns3::Ptr<ns3::MobilityModel> sender_mobility(int s) const {
    return ports_[static_cast<std::size_t>(s)].mobility;
  }
  ns3::Ptr<ns3::MobilityModel> sink_mobility(int network) const {
    return static_cast<std::size_t>(network) < sinks_.size()
               ? sinks_[static_cast<std::size_t>(network)]
               : ns3::Ptr<ns3::MobilityModel>();
  }
  const Sender& sender(int s) const { return senders_[static_cast<std::size_t>(s)]; }
  // The first of `count` ns-3 random-stream numbers for a network being built. Every kind assigns
  // fixed streams to what draws random numbers (its helper's AssignStreams): ns-3's automatic
  // stream numbers run on across the runs of a process, so a run would depend on what ran before
  // it in the same process.
  std::int64_t streams(std::int64_t count) {
    const std::int64_t first = next_stream_;
    next_stream_ += count;
    return first;
  }

  // Keeps `object` alive until the run's simulation ends (a helper that disposes of its channel
  // when destroyed, e.g. ns-3's LrWpanHelper).
  void keep(std::shared_ptr<void> object) { kept_.push_back(std::move(object)); }

  // Sender `s` sends packet `id` now (called by an ns-3 event at the send time).
  void send_now(int s, std::uint64_t id);
  // Starts the background nodes' own traffic (Traffic::kPoisson, kSaturated), once every network
  // is built: their random streams follow the kinds'.
  void start_traffic();
  // Where fates are appended while ns-3 runs (NetworkRun::advance_to).
  void collect_into(std::vector<Fate>* fates) { fates_ = fates; }

 private:
  bool received(ns3::Ptr<ns3::NetDevice> device, ns3::Ptr<const ns3::Packet> p,
                std::uint16_t protocol, const ns3::Address& from);
  void note(const ns3::Ptr<const ns3::Packet>& p, Drop drop);
  // Reports packet `seq`'s fate once (a sensor's into the fates, a background node's counted).
  // `refill`: a saturated node replaces the packet (not when the device refused it at once).
  void fate(std::uint64_t seq, Drop drop, bool refill = true);
  void background_send(int s);  // a background node's next packet
  void poisson_arrival(int s);  // ... and, for a Poisson node, the next arrival

  struct Port {
    ns3::Ptr<ns3::NetDevice> device;
    ns3::Address sink;
    bool confirms = false;
    std::deque<std::uint64_t> unconfirmed;  // sequence numbers, oldest first
    MacCounters counters;
    ns3::Ptr<ns3::MobilityModel> mobility;           // set by kinds with positions
    std::uint64_t last_attempt = ~std::uint64_t{0};  // the packet of its last attempt
    ns3::Ptr<ns3::ExponentialRandomVariable> gap;    // a Poisson node's inter-arrival time (s)
  };
  struct InFlight {
    int sender;
    std::uint64_t id;
  };
  std::vector<Sender> senders_;
  std::vector<Port> ports_;
  // Every packet sent and not yet delivered or dropped, by its sequence number (its tag): a
  // packet's fate is reported once, so neither a duplicate reception (a retransmission after a
  // lost acknowledgement) nor a drop after a delivery is.
  std::unordered_map<std::uint64_t, InFlight> in_flight_;
  std::uint64_t next_seq_ = 0;
  std::vector<std::uint8_t> payload_;  // zero bytes: a packet's content is its tag
  std::vector<Fate>* fates_ = nullptr;
  std::int64_t next_stream_ = 0;
  int building_ = 0;                                 // the network being built
  std::vector<ns3::Ptr<ns3::MobilityModel>> sinks_;  // per network (kinds with positions)
  std::uint64_t next_background_id_ = 0;
  std::vector<std::shared_ptr<void>> kept_;
};

// The EtherType-like protocol number of ncosim's packets (IEEE 802 local experimental 1).
inline constexpr std::uint16_t kProtocol = 0x88B5;

}  // namespace ncosim::network
