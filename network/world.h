// network/world.h — one run's ns-3 simulation (builds with ns-3 only): the nodes, their devices,
// where each sender's packets go, and what the stack did to them. The network kinds' build()
// add their nodes and devices here (network/network.h).
#pragma once

#include <ns3/address.h>
#include <ns3/net-device.h>
#include <ns3/packet.h>
#include <ns3/ptr.h>

#include <cstdint>
#include <vector>

#include "network/network.h"

namespace ncosim::network {

class World {
 public:
  explicit World(std::vector<Sender> senders);
  // The network being built: the sink's device (packets addressed to it are deliveries) and each
  // sender's device (it sends to `sink`, the sink device's address).
  void attach_sink(const ns3::Ptr<ns3::NetDevice>& device);
  void attach_sender(int sender, const ns3::Ptr<ns3::NetDevice>& device, const ns3::Address& sink);
  // Connects the drop trace source `trace` of a sender's device: a packet it fires for is lost
  // for `cause`.
  void connect_drop(const ns3::Ptr<ns3::NetDevice>& device, const char* trace, Drop cause);
  void dropped(Drop cause, const ns3::Ptr<const ns3::Packet>& p);
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

  // Sender `s` sends packet `id` now (called by an ns-3 event at the send time).
  void send_now(int s, std::uint64_t id);
  // Where fates are appended while ns-3 runs (Session::advance_to).
  void collect_into(std::vector<Fate>* fates) { fates_ = fates; }

 private:
  bool received(ns3::Ptr<ns3::NetDevice> device, ns3::Ptr<const ns3::Packet> p,
                std::uint16_t protocol, const ns3::Address& from);
  void note(const ns3::Ptr<const ns3::Packet>& p, Drop drop);

  struct Port {
    ns3::Ptr<ns3::NetDevice> device;
    ns3::Address sink;
  };
  std::vector<Sender> senders_;
  std::vector<Port> ports_;
  std::vector<std::uint8_t> payload_;  // zero bytes: a packet's content is its tag
  std::vector<Fate>* fates_ = nullptr;
  std::int64_t next_stream_ = 0;
};

// The EtherType-like protocol number of ncosim's packets (IEEE 802 local experimental 1).
inline constexpr std::uint16_t kProtocol = 0x88B5;

}  // namespace ncosim::network
