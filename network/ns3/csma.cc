// network/ns3/csma.cc — the `csma` network: a wired bus (ns-3's CSMA model: one shared half-duplex
// channel, carrier sense with exponential back-off, a drop-tail queue per device). It is the
// network whose delays can be computed by hand: a packet alone on the bus arrives after its
// transmission time, (payload + 18 bytes of Ethernet header and trailer) x 8 / rate, plus the
// propagation delay.
#include <fmt/format.h>

#include <cmath>
#include <memory>

#include "kernel/check.h"
#include "network/network.h"
#include "network/ns3/ns3_network.h"

#if NCOSIM_HAVE_NS3
#include <ns3/csma-helper.h>
#include <ns3/node-container.h>
#include <ns3/queue-size.h>

#include "network/ns3/world.h"
#endif

namespace ncosim::network {

namespace {

using config::Key;

const config::Keys& csma_keys() {
  static const config::Keys keys{
      Key::number("rate")
          .range(1.0, 1e12)
          .says("a bit rate in 1..1e12 bit/s")
          .or_default(10e6)
          .unit("bit/s")
          .help("the bus's bit rate (whole bit/s)"),
      Key::number("delay")
          .range(0.0, 1.0)
          .says("a delay in 0..1 s")
          .or_default(1e-6)
          .unit("s")
          .help("propagation delay from any node to any other (rounded to ns; 1 us is about "
                "200 m of cable)"),
      Key::integer("queue")
          .range(1, 1'000'000)
          .or_default(100)
          .unit("packets")
          .help("drop-tail transmit queue of each node's device; a packet that finds it full is "
                "dropped (cause queue)"),
  };
  return keys;
}

#if NCOSIM_HAVE_NS3
// ns-3's CSMA puts a frame on the wire once: a busy bus defers it (back-off) before PhyTxBegin, and
// the model has no collisions, so no frame is sent twice.
void attempted(World* world, int sender, ns3::Ptr<const ns3::Packet> p) {
  world->attempt_packet(sender, p);
}
#endif

class CsmaDesign final : public Ns3Network {
 public:
  CsmaDesign(std::uint64_t rate, std::int64_t delay_ns, std::uint32_t queue)
      : rate_(rate), delay_ns_(delay_ns), queue_(queue) {}
  void build(World& world, const std::vector<int>& senders) const override;
  bool carries_actuators() const override { return true; }
  // Measured (peak RSS of one run, 20 and 80 saturating Poisson nodes, queue 10,000): 230 to 340
  // bytes a queued packet; the bus surely carries rate / (8 x 1538) frames a second (full frames).
  Footprint footprint() const override {
    return {64e3, 400.0, static_cast<double>(queue_), static_cast<double>(rate_) / (8.0 * 1538.0)};
  }

 private:
  std::uint64_t rate_;
  std::int64_t delay_ns_;
  std::uint32_t queue_;
};

#if NCOSIM_HAVE_NS3
void CsmaDesign::build(World& world, const std::vector<int>& senders) const {
  ns3::NodeContainer nodes = world.create_nodes(senders);
  ns3::CsmaHelper csma;
  csma.SetChannelAttribute("DataRate", ns3::DataRateValue(ns3::DataRate(rate_)));
  csma.SetChannelAttribute("Delay", ns3::TimeValue(ns3::NanoSeconds(delay_ns_)));
  csma.SetQueue("ns3::DropTailQueue<Packet>", "MaxSize",
                ns3::QueueSizeValue(ns3::QueueSize(ns3::QueueSizeUnit::PACKETS, queue_)));
  const ns3::NetDeviceContainer devices = csma.Install(nodes);
  const std::int64_t first = world.streams(static_cast<std::int64_t>(devices.GetN()));
  const std::int64_t used = csma.AssignStreams(devices, first);
  NCOSIM_CHECK(used <= static_cast<std::int64_t>(devices.GetN()));
  world.attach_all(devices, senders, false,
                   [&world](int s, const ns3::Ptr<ns3::NetDevice>& device) {
                     world.connect_drop(device, "MacTxDrop", Drop::kQueue);
                     world.connect_drop(device, "PhyTxDrop", Drop::kChannelAccess);
                     const bool connected = device->TraceConnectWithoutContext(
                         "PhyTxBegin", ns3::MakeBoundCallback(&attempted, &world, s));
                     NCOSIM_CHECK(connected);
                   });
}
#else
void CsmaDesign::build(World&, const std::vector<int>&) const { NCOSIM_CHECK(false); }
#endif

std::shared_ptr<const NetworkDesign> read_csma(const config::Table& t) {
  const config::KeyReader r(t, csma_keys());
  auto design = std::make_shared<CsmaDesign>(
      static_cast<std::uint64_t>(std::llround(r.number("rate"))),
      std::llround(r.number("delay") * 1e9), static_cast<std::uint32_t>(r.integer("queue")));
  if (!have_ns3()) t.fail("kind", without_ns3_message());
  return design;
}

}  // namespace

void register_csma(NetworkRegistry& registry) {
  registry.add("csma",
               "wired bus (ns-3 CSMA: carrier sense, back-off, drop-tail queues): rate, delay, "
               "queue",
               csma_keys(), read_csma);
}

}  // namespace ncosim::network
