// network/ns3/world.cc — one run's ns-3 world (builds with ns-3; network/ns3/world.h): the nodes
// the kinds build, the tag that names each packet, and what the stack did to each packet.
#include "network/ns3/world.h"

#include <ns3/constant-position-mobility-model.h>
#include <ns3/double.h>
#include <ns3/simulator.h>
#include <ns3/tag.h>

#include <algorithm>
#include <cmath>
#include <utility>

#include "kernel/check.h"

namespace ncosim::network {

namespace {

// A packet's sequence number in the run (World::send_now), carried as an ns-3 packet tag (not in
// the payload, whose bytes the stack counts as they are).
class PacketTag final : public ns3::Tag {
 public:
  PacketTag() = default;
  explicit PacketTag(std::uint64_t seq) : seq_(seq) {}
  static ns3::TypeId GetTypeId() {
    static ns3::TypeId tid =
        ns3::TypeId("ncosim::network::PacketTag").SetParent<ns3::Tag>().AddConstructor<PacketTag>();
    return tid;
  }
  ns3::TypeId GetInstanceTypeId() const override { return GetTypeId(); }
  std::uint32_t GetSerializedSize() const override { return 8; }
  void Serialize(ns3::TagBuffer b) const override { b.WriteU64(seq_); }
  void Deserialize(ns3::TagBuffer b) override { seq_ = b.ReadU64(); }
  void Print(std::ostream& os) const override { os << "seq=" << seq_; }
  std::uint64_t seq() const { return seq_; }

 private:
  std::uint64_t seq_ = 0;
};

void drop_trace(World* world, Drop cause, ns3::Ptr<const ns3::Packet> p) {
  world->dropped(cause, p);
}

}  // namespace

World::World(std::vector<Sender> senders) : senders_(std::move(senders)), ports_(senders_.size()) {}

void World::attach_sink(const ns3::Ptr<ns3::NetDevice>& device) {
  device->SetReceiveCallback(ns3::MakeCallback(&World::received, this));
}

void World::attach_sender(int sender, const ns3::Ptr<ns3::NetDevice>& device,
                          const ns3::Address& sink, bool confirms) {
  Port& port = ports_[static_cast<std::size_t>(sender)];
  port.device = device;
  port.sink = sink;
  port.confirms = confirms;
}

ns3::NodeContainer World::create_nodes(const std::vector<int>& senders) const {
  const auto downlinks =
      std::count_if(senders.begin(), senders.end(), [&](int s) { return sender(s).downlink; });
  ns3::NodeContainer nodes;
  nodes.Create(
      static_cast<std::uint32_t>(1 + senders.size() + static_cast<std::size_t>(downlinks)));
  return nodes;
}

ns3::Ptr<ns3::MobilityModel> World::place(std::uint32_t node, const std::vector<int>& senders,
                                          const std::array<double, 3>& sink) {
  auto position = ns3::CreateObject<ns3::ConstantPositionMobilityModel>();
  if (node == 0 || node > senders.size()) {  // the sink, or a controller's transmitter beside it
    position->SetPosition(ns3::Vector(sink[0], sink[1], sink[2]));
    if (node == 0) mobile_sink(position);
  } else {
    const int s = senders[node - 1];
    position->SetPosition(ns3::Vector(sender(s).x, sender(s).y, sender(s).z));
    mobile_sender(s, position);
  }
  return position;
}

void World::attach_all(const ns3::NetDeviceContainer& devices, const std::vector<int>& senders,
                       bool confirms, const Connect& connect) {
  attach_sink(devices.Get(0));
  auto transmitter = static_cast<std::uint32_t>(1 + senders.size());
  for (std::size_t i = 0; i < senders.size(); ++i) {
    ns3::Ptr<ns3::NetDevice> device = devices.Get(static_cast<std::uint32_t>(i + 1));
    ns3::Ptr<ns3::NetDevice> to = devices.Get(0);
    if (sender(senders[i]).downlink) {  // the actuator's node receives
      attach_sink(device);
      to = device;
      device = devices.Get(transmitter++);
    }
    attach_sender(senders[i], device, to->GetAddress(), confirms);
    connect(senders[i], device);
  }
}

void World::send_now(int s, std::uint64_t id) {
  Port& port = ports_[static_cast<std::size_t>(s)];
  const std::uint32_t bytes = sender(s).bytes;
  if (payload_.size() < bytes) payload_.resize(bytes, 0);
  auto p = ns3::Create<ns3::Packet>(payload_.data(), bytes);
  const std::uint64_t seq = next_seq_++;
  in_flight_.emplace(seq, InFlight{s, id});
  if (port.confirms) port.unconfirmed.push_back(seq);
  p->AddPacketTag(PacketTag(seq));
  // A device that refuses the packet (e.g. a full queue) may have fired a drop trace already (then
  // this fate is not reported again); a refusal without a trace is a drop at the queue too.
  if (!port.device->Send(p, port.sink, kProtocol)) {
    if (port.confirms && !port.unconfirmed.empty() && port.unconfirmed.back() == seq)
      port.unconfirmed.pop_back();
    fate(seq, Drop::kQueue, false);  // not replaced at once: a refusal could repeat forever
  }
}

void World::connect_drop(const ns3::Ptr<ns3::NetDevice>& device, const char* trace, Drop cause) {
  const bool connected =
      device->TraceConnectWithoutContext(trace, ns3::MakeBoundCallback(&drop_trace, this, cause));
  NCOSIM_CHECK(connected);
}

void World::attempt_packet(int s, const ns3::Ptr<const ns3::Packet>& p) {
  PacketTag tag;
  if (!p->PeekPacketTag(tag)) return;  // not one of ncosim's packets
  Port& port = ports_[static_cast<std::size_t>(s)];
  attempt(s, tag.seq() == port.last_attempt);
  port.last_attempt = tag.seq();
}

void World::dropped(Drop cause, const ns3::Ptr<const ns3::Packet>& p) { note(p, cause); }

void World::confirmed(int sender, Drop drop) {
  Port& port = ports_[static_cast<std::size_t>(sender)];
  NCOSIM_CHECK(!port.unconfirmed.empty());
  const std::uint64_t seq = port.unconfirmed.front();
  port.unconfirmed.pop_front();
  if (drop != Drop::kNone) fate(seq, drop);
}

bool World::received(ns3::Ptr<ns3::NetDevice>, ns3::Ptr<const ns3::Packet> p, std::uint16_t,
                     const ns3::Address&) {
  note(p, Drop::kNone);
  return true;
}

void World::note(const ns3::Ptr<const ns3::Packet>& p, Drop drop) {
  PacketTag tag;
  if (p->PeekPacketTag(tag)) fate(tag.seq(), drop);
}

void World::fate(std::uint64_t seq, Drop drop, bool refill) {
  const auto it = in_flight_.find(seq);
  if (it == in_flight_.end()) return;  // its fate is known already
  const int s = it->second.sender;
  MacCounters& c = ports_[static_cast<std::size_t>(s)].counters;
  if (drop == Drop::kNone)
    ++c.delivered;
  else
    ++c.dropped[static_cast<int>(drop)];
  const Traffic traffic = sender(s).traffic;
  if (traffic == Traffic::kSensor) {
    NCOSIM_CHECK(fates_ != nullptr);
    fates_->push_back(Fate{s, it->second.id, ns3::Simulator::Now().GetNanoSeconds(), drop});
  }
  in_flight_.erase(it);
  // A saturated node replaces every packet the stack is done with, as an event of its own (not
  // inside the MAC's callback that reported the fate).
  if (traffic == Traffic::kSaturated && refill)
    ns3::Simulator::ScheduleNow(&World::background_send, this, s);
}

// A saturated node keeps this many packets handed over and not yet delivered or dropped: one in
// the MAC's hands and one waiting, so that it has a packet to send the moment it is done with one.
constexpr int kSaturatedBacklog = 2;

void World::start_traffic() {
  for (std::size_t i = 0; i < senders_.size(); ++i) {
    const int s = static_cast<int>(i);
    const Sender& x = senders_[i];
    if (x.traffic == Traffic::kSaturated) {
      for (int k = 0; k < kSaturatedBacklog; ++k)
        ns3::Simulator::ScheduleNow(&World::background_send, this, s);
    } else if (x.traffic == Traffic::kPoisson) {
      auto gap = ns3::CreateObject<ns3::ExponentialRandomVariable>();
      gap->SetAttribute("Mean", ns3::DoubleValue(1.0 / x.rate));
      gap->SetStream(streams(1));
      ports_[i].gap = gap;
      ns3::Simulator::Schedule(ns3::NanoSeconds(std::llround(gap->GetValue() * 1e9)),
                               &World::poisson_arrival, this, s);
    }
  }
}

void World::background_send(int s) { send_now(s, next_background_id_++); }

void World::poisson_arrival(int s) {
  background_send(s);
  const double gap = ports_[static_cast<std::size_t>(s)].gap->GetValue();
  ns3::Simulator::Schedule(ns3::NanoSeconds(std::llround(gap * 1e9)), &World::poisson_arrival, this,
                           s);
}

}  // namespace ncosim::network
