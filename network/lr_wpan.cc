// network/lr_wpan.cc — the `lr_wpan` network: IEEE 802.15.4 (2.4 GHz O-QPSK, 250 kb/s), ns-3's
// lr-wpan model, the wireless sensor network case. Every sender is a device of one PAN with the
// sink as its destination; frames go by unslotted CSMA/CA and are acknowledged, with up to three
// retransmissions (the standard's macMaxFrameRetries); the channel is one spectrum channel with a
// log-distance path loss from the nodes' fixed positions, and a frame is received with the
// probability of ns-3's 802.15.4 error model at its signal-to-interference-and-noise ratio, so
// frames of different nodes that overlap in time collide.
#include <fmt/format.h>

#include <algorithm>
#include <memory>

#include "kernel/check.h"
#include "network/network.h"

#if NCOSIM_HAVE_NS3
#include <ns3/boolean.h>
#include <ns3/constant-position-mobility-model.h>
#include <ns3/double.h>
#include <ns3/lr-wpan-helper.h>
#include <ns3/lr-wpan-mac.h>
#include <ns3/lr-wpan-net-device.h>
#include <ns3/lr-wpan-spectrum-value-helper.h>
#include <ns3/node-container.h>
#include <ns3/propagation-delay-model.h>
#include <ns3/propagation-loss-model.h>
#include <ns3/single-model-spectrum-channel.h>

#include "network/world.h"
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
      Key::numbers("sink_position")
          .optional("[0, 0, 0]")
          .unit("m")
          .help("[x, y, z] of the sink, the estimators' node"),
      Key::number("path_loss_exponent")
          .range(1.0, 8.0)
          .says("an exponent in 1..8")
          .or_default(3.0)
          .help("log-distance path loss: L(d) = reference_loss + 10 exponent log10(d / 1 m)"),
      Key::number("reference_loss")
          .range(0.0, 200.0)
          .says("a loss in 0..200 dB")
          .or_default(46.6777)
          .unit("dB")
          .help("path loss at 1 m (the default: free space at 2.4 GHz)"),
  };
  return keys;
}

class LrWpanDesign final : public NetworkDesign {
 public:
  double tx_power = 0.0, exponent = 3.0, reference_loss = 46.6777;
  double sink[3] = {0.0, 0.0, 0.0};
  void build(World& world, const std::vector<int>& senders) const override;
  bool has_positions() const override { return true; }
  std::uint32_t max_payload() const override { return kMaxPayload; }
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

void confirmed(World* world, int sender, ns3::McpsDataConfirmParams params) {
  world->confirmed(sender, drop_of(params.m_status));
}

void LrWpanDesign::build(World& world, const std::vector<int>& senders) const {
  const auto downlinks = static_cast<std::size_t>(std::count_if(
      senders.begin(), senders.end(), [&](int s) { return world.sender(s).downlink; }));
  ns3::NodeContainer nodes;
  // The sink first, then the senders' nodes, then the controller's transmitters (network.h).
  nodes.Create(static_cast<std::uint32_t>(1 + senders.size() + downlinks));
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
  for (std::uint32_t i = 0; i < devices.GetN(); ++i) {
    auto device = ns3::DynamicCast<ns3::LrWpanNetDevice>(devices.Get(i));
    auto position = ns3::CreateObject<ns3::ConstantPositionMobilityModel>();
    if (i == 0 || i > senders.size()) {  // the sink, or a controller's transmitter beside it
      position->SetPosition(ns3::Vector(sink[0], sink[1], sink[2]));
    } else {
      const Sender& s = world.sender(senders[i - 1]);
      position->SetPosition(ns3::Vector(s.x, s.y, s.z));
    }
    device->GetPhy()->SetMobility(position);
    device->GetPhy()->SetTxPowerSpectralDensity(psd.CreateTxPowerSpectralDensity(tx_power, 11));
    device->SetAttribute("UseAcks", ns3::BooleanValue(true));
  }
  constexpr std::int64_t kStreamsPerDevice = 8;
  const std::int64_t count = kStreamsPerDevice * static_cast<std::int64_t>(devices.GetN());
  const std::int64_t used = helper.AssignStreams(devices, world.streams(count));
  NCOSIM_CHECK(used <= count);
  world.attach_sink(devices.Get(0));
  auto transmitter = static_cast<std::uint32_t>(1 + senders.size());
  for (std::size_t i = 0; i < senders.size(); ++i) {
    auto device =
        ns3::DynamicCast<ns3::LrWpanNetDevice>(devices.Get(static_cast<std::uint32_t>(i + 1)));
    auto to = devices.Get(0);
    if (world.sender(senders[i]).downlink) {  // the actuator's node receives
      world.attach_sink(device);
      to = device;
      device = ns3::DynamicCast<ns3::LrWpanNetDevice>(devices.Get(transmitter++));
    }
    world.attach_sender(senders[i], device, to->GetAddress(), true);
    device->GetMac()->SetMcpsDataConfirmCallback(
        ns3::MakeBoundCallback(&confirmed, &world, senders[i]));
  }
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
  if (r.has("sink_position")) {
    const std::vector<double> p = r.numbers("sink_position");
    if (p.size() != 3)
      t.fail("sink_position", fmt::format("expected [x, y, z] (m), got {} numbers", p.size()));
    for (int i = 0; i < 3; ++i) d->sink[i] = p[static_cast<std::size_t>(i)];
  }
  if (!have_ns3()) t.fail("kind", without_ns3_message());
  return d;
}

}  // namespace

void register_lr_wpan(NetworkRegistry& registry) {
  registry.add("lr_wpan",
               "IEEE 802.15.4 (ns-3 lr-wpan: 250 kb/s, unslotted CSMA/CA, acknowledged frames, "
               "log-distance path loss): tx_power, sink_position, path_loss_exponent, "
               "reference_loss",
               lr_wpan_keys(), read_lr_wpan);
}

}  // namespace ncosim::network
