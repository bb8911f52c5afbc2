// network/ns3/lr_wpan.cc — the `lr_wpan` network: IEEE 802.15.4 (2.4 GHz O-QPSK, 250 kb/s), ns-3's
// lr-wpan model, the wireless sensor network case. Every sender is a device of one PAN with the
// sink as its destination; frames go by unslotted CSMA/CA and are acknowledged, with up to
// max_frame_retries retransmissions (the standard's macMaxFrameRetries, 3); the channel is one
// spectrum channel with a log-distance path loss from the nodes' fixed positions, and a frame is
// received with the probability of ns-3's 802.15.4 error model at its
// signal-to-interference-and-noise ratio, so frames of different nodes that overlap in time
// collide.
#include <fmt/format.h>

#include <cmath>
#include <memory>

#include "kernel/check.h"
#include "network/network.h"
#include "network/ns3/ns3_network.h"

#if NCOSIM_HAVE_NS3
#include <ns3/boolean.h>
#include <ns3/double.h>
#include <ns3/lr-wpan-helper.h>
#include <ns3/lr-wpan-mac.h>
#include <ns3/lr-wpan-net-device.h>
#include <ns3/lr-wpan-spectrum-value-helper.h>
#include <ns3/node-container.h>
#include <ns3/propagation-delay-model.h>
#include <ns3/propagation-loss-model.h>
#include <ns3/simulator.h>
#include <ns3/single-model-spectrum-channel.h>

#include "network/ns3/world.h"
#endif

namespace ncosim::network {

namespace {

using config::Key;

// The largest payload of one frame: ns-3's LrWpanNetDevice MTU (114 bytes: aMaxPHYPacketSize, 127,
// less the largest MAC header and the frame check sequence); its Send refuses a larger packet.
constexpr std::uint32_t kMaxPayload = 114;

const config::Keys& lr_wpan_keys() {
  static const config::Keys keys{
      Key::number("tx_power")
          .range(-40.0, 20.0)
          .says("a power in -40..20 dBm")
          .or_default(0.0)
          .unit("dBm")
          .help("transmit power of every node"),
      sink_position_key(),
      path_loss_exponent_key(),
      Key::number("reference_loss")
          .range(0.0, 200.0)
          .says("a loss in 0..200 dB")
          .or_default(46.6777)
          .unit("dB")
          .help("path loss at 1 m (the default is ns-3's LogDistancePropagationLossModel default, "
                "free "
                "space at 5.15 GHz; free space at 2.4 GHz would be 40.05 dB)"),
      Key::integer("max_frame_retries")
          .range(0, 7)
          .or_default(3)
          .unit("frames")
          .help("retransmissions of an unacknowledged frame before the MAC drops it "
                "(macMaxFrameRetries)"),
  };
  return keys;
}

// The least power (dBm) at which ns-3.37's 802.15.4 receiver starts to receive a frame: LrWpanPhy
// drops a frame whose signal-to-interference-and-noise ratio is below -5 dB when it starts, and the
// noise alone is the thermal noise k T (T = 290 K, noise factor 1) over the five 1 MHz bands of
// the channel (LrWpanSpectrumValueHelper::CreateNoisePowerSpectralDensity): -106.99 dBm. Its
// `rxSensitivity` (-106.58 dBm) only sets the clear channel assessment and energy detection
// thresholds; at that power a frame of 50 bytes is still received with probability 0.97.
double noise_dbm() { return 10.0 * std::log10(1.3803e-23 * 290.0 * 5e6) + 30.0; }
constexpr double kMinSinrDb = -5.0;

class LrWpanDesign final : public Ns3Network {
 public:
  double tx_power = 0.0, exponent = 3.0, reference_loss = 46.6777;
  std::array<double, 3> sink{};
  int max_frame_retries = 3;
  void build(World& world, const std::vector<int>& senders) const override;
  bool has_positions() const override { return true; }
  // Measured (peak RSS of one run): 19 KB a node (400 saturated background nodes), 125 to 330
  // bytes a queued packet (20 and 80 Poisson nodes at 2,000 and 20,000 packets/s); ns-3's 802.15.4
  // queue has no bound, and its channel carries fewer than about 300 frames a second.
  Footprint footprint() const override { return {32e3, 400.0, 1e300, 100.0}; }
  bool carries_actuators() const override { return true; }
  std::uint32_t max_payload() const override { return kMaxPayload; }
  // ns-3's LogDistancePropagationLossModel (reference distance 1 m, no loss beyond the reference
  // loss closer than that) applied to tx_power.
  double received_dbm(double distance_m) const {
    return tx_power - reference_loss -
           (distance_m > 1.0 ? 10.0 * exponent * std::log10(distance_m) : 0.0);
  }
  double threshold_dbm() const { return noise_dbm() + kMinSinrDb; }
  std::optional<Reach> reach(const double (&p)[3]) const override {
    Reach r;
    r.distance_m = std::hypot(p[0] - sink[0], p[1] - sink[1], p[2] - sink[2]);
    r.received_dbm = received_dbm(r.distance_m);
    r.threshold_dbm = threshold_dbm();
    r.threshold_why = fmt::format(
        "ns-3's 802.15.4 receiver drops a frame below {} dB of signal to noise, and its noise "
        "floor is {:.2f} dBm",
        kMinSinrDb, noise_dbm());
    return r;
  }
};

#if NCOSIM_HAVE_NS3
Drop drop_of(ns3::LrWpanMcpsDataConfirmStatus status) {
  switch (status) {
    case ns3::IEEE_802_15_4_SUCCESS:
      return Drop::kNone;
    case ns3::IEEE_802_15_4_CHANNEL_ACCESS_FAILURE:
      return Drop::kChannelAccess;
    case ns3::IEEE_802_15_4_TRANSACTION_OVERFLOW:
      return Drop::kQueue;
    default:  // IEEE_802_15_4_NO_ACK (and statuses a data frame to the sink cannot get)
      return Drop::kNoAck;
  }
}

// A frame the MAC gave up on: from a sender out of the sink's range (LrWpanDesign::reach, at the
// nodes' positions now: they may ride SUMO vehicles), no retransmission could have helped.
void confirmed(World* world, const LrWpanDesign* design, int sender,
               ns3::Ptr<ns3::MobilityModel> sink, ns3::McpsDataConfirmParams params) {
  Drop drop = drop_of(params.m_status);
  if (drop == Drop::kNoAck) {
    const double d = world->sender_mobility(sender)->GetDistanceFrom(sink);
    if (design->received_dbm(d) < design->threshold_dbm()) drop = Drop::kOutOfRange;
  }
  world->confirmed(sender, drop);
}

void attempted(World* world, int sender, ns3::Ptr<const ns3::Packet> p) {
  world->attempt_packet(sender, p);
}

// The time a sender's transceiver is busy: transmitting, or receiving a frame it synchronised to
// (another node's, or an acknowledgement), i.e. the channel as this node finds it occupied.
struct BusyClock {
  World* world = nullptr;
  int sender = 0;
  std::int64_t since = -1;  // ns; -1: not busy
};

void trx_state(BusyClock* c, ns3::LrWpanPhyEnumeration, ns3::LrWpanPhyEnumeration now) {
  const bool busy = now == ns3::IEEE_802_15_4_PHY_BUSY_RX || now == ns3::IEEE_802_15_4_PHY_BUSY_TX;
  const std::int64_t t = ns3::Simulator::Now().GetNanoSeconds();
  if (busy && c->since < 0) c->since = t;
  if (!busy && c->since >= 0) {
    c->world->busy(c->sender, t - c->since);
    c->since = -1;
  }
}

void LrWpanDesign::build(World& world, const std::vector<int>& senders) const {
  ns3::NodeContainer nodes = world.create_nodes(senders);
  auto channel = ns3::CreateObject<ns3::SingleModelSpectrumChannel>();
  auto loss = ns3::CreateObject<ns3::LogDistancePropagationLossModel>();
  loss->SetAttribute("Exponent", ns3::DoubleValue(exponent));
  loss->SetAttribute("ReferenceLoss", ns3::DoubleValue(reference_loss));
  channel->AddPropagationLossModel(loss);
  channel->SetPropagationDelayModel(ns3::CreateObject<ns3::ConstantSpeedPropagationDelayModel>());
  // The helper disposes of its channel when destroyed: it lives as long as the run's simulation.
  auto kept = std::make_shared<ns3::LrWpanHelper>();
  world.keep(kept);
  ns3::LrWpanHelper& helper = *kept;
  helper.SetChannel(channel);
  const ns3::NetDeviceContainer devices = helper.Install(nodes);
  helper.AssociateToPan(devices, 1);
  ns3::LrWpanSpectrumValueHelper psd;
  ns3::Ptr<ns3::MobilityModel> sink_at;
  for (std::uint32_t i = 0; i < devices.GetN(); ++i) {
    auto device = ns3::DynamicCast<ns3::LrWpanNetDevice>(devices.Get(i));
    const ns3::Ptr<ns3::MobilityModel> position = world.place(i, senders, sink);
    if (i == 0) sink_at = position;
    device->GetPhy()->SetMobility(position);
    device->GetPhy()->SetTxPowerSpectralDensity(psd.CreateTxPowerSpectralDensity(tx_power, 11));
    device->SetAttribute("UseAcks", ns3::BooleanValue(true));
    device->GetMac()->SetMacMaxFrameRetries(static_cast<std::uint8_t>(max_frame_retries));
  }
  constexpr std::int64_t kStreamsPerDevice = 8;
  const std::int64_t count = kStreamsPerDevice * static_cast<std::int64_t>(devices.GetN());
  const std::int64_t used = helper.AssignStreams(devices, world.streams(count));
  NCOSIM_CHECK(used <= count);
  world.attach_all(devices, senders, true, [&](int s, const ns3::Ptr<ns3::NetDevice>& d) {
    auto device = ns3::DynamicCast<ns3::LrWpanNetDevice>(d);
    device->GetMac()->SetMcpsDataConfirmCallback(
        ns3::MakeBoundCallback(&confirmed, &world, this, s, sink_at));
    const bool tx = device->GetMac()->TraceConnectWithoutContext(
        "MacTx", ns3::MakeBoundCallback(&attempted, &world, s));
    auto clock = std::make_shared<BusyClock>(BusyClock{&world, s, -1});
    world.keep(clock);
    world.busy(s, 0);  // exposed, even if never busy
    const bool state = device->GetPhy()->TraceConnectWithoutContext(
        "TrxStateValue", ns3::MakeBoundCallback(&trx_state, clock.get()));
    NCOSIM_CHECK(tx && state);
  });
}
#else
void LrWpanDesign::build(World&, const std::vector<int>&) const { NCOSIM_CHECK(false); }
#endif

std::shared_ptr<const NetworkDesign> read_lr_wpan(const config::Table& t) {
  const config::KeyReader r(t, lr_wpan_keys());
  auto d = std::make_shared<LrWpanDesign>();
  d->tx_power = r.number("tx_power");
  d->exponent = r.number("path_loss_exponent");
  d->reference_loss = r.number("reference_loss");
  d->max_frame_retries = static_cast<int>(r.integer("max_frame_retries"));
  if (r.has("sink_position")) d->sink = read_xyz(t, r, "sink_position");
  if (!have_ns3()) t.fail("kind", without_ns3_message());
  return d;
}

}  // namespace

void register_lr_wpan(NetworkRegistry& registry) {
  registry.add("lr_wpan",
               "IEEE 802.15.4 (ns-3 lr-wpan: 250 kb/s, unslotted CSMA/CA, acknowledged frames, "
               "log-distance path loss): tx_power, sink_position, path_loss_exponent, "
               "reference_loss, max_frame_retries",
               lr_wpan_keys(), read_lr_wpan);
}

}  // namespace ncosim::network
