// network/ns3/wifi.cc — the `wifi` network: IEEE 802.11 (ns-3's wifi model, and its wave module for
// 802.11p). Every node is an ad hoc station (802.11a/g/n: AdhocWifiMac; 802.11p: OCB mode,
// outside the context of a BSS, 10 MHz channels) on one Yans channel with a log-distance path
// loss from the nodes' fixed positions. Each packet is a unicast data frame to the sink, sent by
// DCF (a/g/p) or EDCA's best-effort queue (n) at a constant rate and acknowledged: a frame that
// is not acknowledged is retransmitted after a doubled back-off, up to retry_limit transmissions,
// then dropped (cause no_ack). Frames that overlap at a receiver collide (ns-3's interference
// model at their signal-to-interference-and-noise ratio).
//
// 802.11n runs at 5 GHz (channel 36, 20 MHz, long guard interval, one spatial stream) without
// aggregation: each packet is its own frame, so its fate is its own. 802.11g runs at 2.4 GHz
// (channel 1) with ERP-OFDM rates, 802.11a at 5 GHz (channel 36), 802.11p at 5.86 GHz (channel
// 172, 10 MHz).
#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "kernel/check.h"
#include "network/network.h"
#include "network/ns3/ns3_network.h"

#if NCOSIM_HAVE_NS3
#include <ns3/double.h>
#include <ns3/node-container.h>
#include <ns3/propagation-delay-model.h>
#include <ns3/propagation-loss-model.h>
#include <ns3/string.h>
#include <ns3/uinteger.h>
#include <ns3/wave-mac-helper.h>
#include <ns3/wifi-80211p-helper.h>
#include <ns3/wifi-helper.h>
#include <ns3/wifi-mac-helper.h>
#include <ns3/wifi-mac.h>
#include <ns3/wifi-mpdu.h>
#include <ns3/wifi-net-device.h>
#include <ns3/wifi-phy-state-helper.h>
#include <ns3/wifi-psdu.h>
#include <ns3/yans-wifi-channel.h>
#include <ns3/yans-wifi-helper.h>

#include "network/ns3/world.h"
#endif

namespace ncosim::network {

namespace {

using config::Key;

// What each standard is here: its carrier (for the default reference loss), its base rate (the
// default data mode, and the rate of control frames) and the data modes it accepts.
struct Standard {
  const char* name;
  double carrier_hz;
  const char* base_mode;
  std::vector<std::string> modes;
};

const std::vector<Standard>& standards() {
  static const std::vector<Standard> all{
      {"802.11a",
       5.18e9,
       "OfdmRate6Mbps",
       {"OfdmRate6Mbps", "OfdmRate9Mbps", "OfdmRate12Mbps", "OfdmRate18Mbps", "OfdmRate24Mbps",
        "OfdmRate36Mbps", "OfdmRate48Mbps", "OfdmRate54Mbps"}},
      {"802.11g",
       2.412e9,
       "ErpOfdmRate6Mbps",
       {"ErpOfdmRate6Mbps", "ErpOfdmRate9Mbps", "ErpOfdmRate12Mbps", "ErpOfdmRate18Mbps",
        "ErpOfdmRate24Mbps", "ErpOfdmRate36Mbps", "ErpOfdmRate48Mbps", "ErpOfdmRate54Mbps"}},
      {"802.11n",
       5.18e9,
       "HtMcs0",
       {"HtMcs0", "HtMcs1", "HtMcs2", "HtMcs3", "HtMcs4", "HtMcs5", "HtMcs6", "HtMcs7"}},
      {"802.11p",
       5.86e9,
       "OfdmRate6MbpsBW10MHz",
       {"OfdmRate3MbpsBW10MHz", "OfdmRate4_5MbpsBW10MHz", "OfdmRate6MbpsBW10MHz",
        "OfdmRate9MbpsBW10MHz", "OfdmRate12MbpsBW10MHz", "OfdmRate18MbpsBW10MHz",
        "OfdmRate24MbpsBW10MHz", "OfdmRate27MbpsBW10MHz"}},
  };
  return all;
}

// Free-space path loss at 1 m: 20 log10(4 pi f / c) dB.
double free_space_at_1m(double carrier_hz) {
  constexpr double kPi = 3.14159265358979323846;
  return 20.0 * std::log10(4.0 * kPi * carrier_hz / 299'792'458.0);
}

// Every standard's data modes: the values data_mode may take (the reader then checks the
// standard's own).
std::vector<std::string> all_data_modes() {
  std::vector<std::string> out;
  for (const Standard& s : standards()) out.insert(out.end(), s.modes.begin(), s.modes.end());
  return out;
}

const config::Keys& wifi_keys() {
  static const config::Keys keys{
      Key::choice("standard", {"802.11a", "802.11g", "802.11n", "802.11p"})
          .or_default("802.11a")
          .help("802.11a (5.18 GHz), 802.11g (2.412 GHz, ERP-OFDM), 802.11n (5.18 GHz, 20 MHz, "
                "HT, no aggregation) as ad hoc stations; 802.11p (5.86 GHz, 10 MHz) in OCB mode"),
      Key::number("tx_power")
          .range(-40.0, 40.0)
          .says("a power in -40..40 dBm")
          .or_default(16.0)
          .unit("dBm")
          .help("transmit power of every node"),
      Key::choice("data_mode", all_data_modes())
          .optional(
              "the standard's base rate: OfdmRate6Mbps (a), ErpOfdmRate6Mbps (g), HtMcs0 (n), "
              "OfdmRate6MbpsBW10MHz (p)")
          .help("ns-3's constant rate of data frames: OfdmRate{6,9,12,18,24,36,48,54}Mbps (a), "
                "ErpOfdmRate{6,...,54}Mbps (g), HtMcs0..HtMcs7 (n), "
                "OfdmRate{3,4_5,6,9,12,18,24,27}MbpsBW10MHz (p); acknowledgements go at the "
                "highest basic rate not above it"),
      Key::integer("retry_limit")
          .range(1, 1'000'000)
          .or_default(7)
          .unit("transmissions")
          .help("transmissions of a frame before the MAC drops it (cause no_ack): ns-3's MaxSsrc "
                "and MaxSlrc, the standard's dot11ShortRetryLimit"),
      sink_position_key(),
      path_loss_exponent_key(),
      Key::number("reference_loss")
          .range(0.0, 200.0)
          .says("a loss in 0..200 dB")
          .optional("free space at 1 m at the standard's carrier: 46.7 dB (a, n), 40.1 dB (g), "
                    "47.8 dB (p)")
          .unit("dB")
          .help("path loss at 1 m"),
  };
  return keys;
}

// The largest payload of one packet: ns-3's WifiNetDevice takes up to its MTU, 2296 bytes, above
// the 1500 of every network (its 8-byte LLC/SNAP header is the stack's own, not the payload's).
constexpr std::uint32_t kMaxPayload = 1500;

// The least power (dBm) at which ns-3.37's wifi receiver starts to receive a frame: the
// ThresholdPreambleDetectionModel that WifiPhyHelper installs detects no preamble received below
// its MinimumRssi (-82 dBm) or below its Threshold (4 dB) of signal to noise, the noise being the
// thermal noise k T B (T = 290 K) of the channel's width B (20 MHz; 10 MHz for 802.11p) raised by
// the PHY's RxNoiseFigure (7 dB): -90 dBm (-93 dBm), so the RSSI bound decides.
constexpr double kMinimumRssiDbm = -82.0;
constexpr double kPreambleSnrDb = 4.0;
constexpr double kNoiseFigureDb = 7.0;

class WifiDesign final : public Ns3Network {
 public:
  const Standard* standard = nullptr;
  std::string data_mode;
  double tx_power = 16.0, exponent = 3.0, reference_loss = 46.7;
  std::uint32_t retry_limit = 7;
  std::array<double, 3> sink{};
  void build(World& world, const std::vector<int>& senders) const override;
  bool has_positions() const override { return true; }
  // Measured (peak RSS of one run): 60 KB a node (400 saturated background nodes), 3.7 MB a node
  // whose queue is full (20 and 40 Poisson nodes at 20,000 packets/s): ns-3's WifiMacQueue holds
  // 500 packets, about 7.4 KB each; the slowest standard carries at least 200 frames a second.
  Footprint footprint() const override { return {64e3, 8e3, 500.0, 200.0}; }
  bool carries_actuators() const override { return true; }
  std::uint32_t max_payload() const override { return kMaxPayload; }
  // ns-3's LogDistancePropagationLossModel (reference distance 1 m, no loss beyond the reference
  // loss closer than that) applied to tx_power.
  double received_dbm(double distance_m) const {
    return tx_power - reference_loss -
           (distance_m > 1.0 ? 10.0 * exponent * std::log10(distance_m) : 0.0);
  }
  double noise_dbm() const {
    const double width_hz = std::string(standard->name) == "802.11p" ? 10e6 : 20e6;
    return 10.0 * std::log10(1.3803e-23 * 290.0 * width_hz) + 30.0 + kNoiseFigureDb;
  }
  std::optional<Reach> reach(const double (&p)[3]) const override {
    Reach r;
    r.distance_m = std::hypot(p[0] - sink[0], p[1] - sink[1], p[2] - sink[2]);
    r.received_dbm = received_dbm(r.distance_m);
    const double snr_bound = noise_dbm() + kPreambleSnrDb;
    r.threshold_dbm = std::max(kMinimumRssiDbm, snr_bound);
    r.threshold_why = fmt::format(
        "ns-3's wifi receiver detects no preamble below {} dBm, nor below {} dB over its noise "
        "floor of {:.2f} dBm",
        kMinimumRssiDbm, kPreambleSnrDb, noise_dbm());
    return r;
  }
};

#if NCOSIM_HAVE_NS3
Drop drop_of(ns3::WifiMacDropReason reason) {
  switch (reason) {
    case ns3::WIFI_MAC_DROP_REACHED_RETRY_LIMIT:
      return Drop::kNoAck;
    default:  // a full queue, or a packet that waited in it beyond its lifetime (500 ms)
      return Drop::kQueue;
  }
}

void dropped_mpdu(World* world, ns3::WifiMacDropReason reason, ns3::Ptr<const ns3::WifiMpdu> m) {
  world->dropped(drop_of(reason), m->GetPacket());
}

// Every frame a sender puts on the air is one of its data frames (a sender receives no data, so
// it sends no acknowledgement); a retransmission has the header's Retry bit set.
void tx_begin(World* world, int sender, ns3::WifiConstPsduMap psdus, ns3::WifiTxVector, double) {
  for (const auto& [id, psdu] : psdus) {
    if (psdu->GetNMpdus() > 0 && psdu->GetHeader(0).IsData())
      world->attempt(sender, psdu->GetHeader(0).IsRetry());
  }
}

// The time the sender's PHY sensed others' signals: energy above its clear channel assessment
// threshold (CCA_BUSY) or a frame being received (RX); its own transmissions are not counted.
// (ns-3.37 declares WifiPhyState outside its namespace.)
void phy_state(World* world, int sender, ns3::Time, ns3::Time duration, WifiPhyState state) {
  if (state == WifiPhyState::CCA_BUSY || state == WifiPhyState::RX)
    world->busy(sender, duration.GetNanoSeconds());
}

ns3::Ptr<ns3::YansWifiChannel> make_channel(double exponent, double reference_loss) {
  auto loss = ns3::CreateObject<ns3::LogDistancePropagationLossModel>();
  loss->SetAttribute("Exponent", ns3::DoubleValue(exponent));
  loss->SetAttribute("ReferenceLoss", ns3::DoubleValue(reference_loss));
  loss->SetAttribute("ReferenceDistance", ns3::DoubleValue(1.0));
  auto channel = ns3::CreateObject<ns3::YansWifiChannel>();
  channel->SetPropagationLossModel(loss);
  channel->SetPropagationDelayModel(ns3::CreateObject<ns3::ConstantSpeedPropagationDelayModel>());
  return channel;
}

ns3::NetDeviceContainer install(const WifiDesign& d, const ns3::NodeContainer& nodes) {
  const std::string name = d.standard->name;
  const bool p = name == "802.11p";
  std::unique_ptr<ns3::WifiHelper> wifi =
      p ? std::make_unique<ns3::Wifi80211pHelper>() : std::make_unique<ns3::WifiHelper>();
  wifi->SetStandard(p                   ? ns3::WIFI_STANDARD_80211p
                    : name == "802.11g" ? ns3::WIFI_STANDARD_80211g
                    : name == "802.11n" ? ns3::WIFI_STANDARD_80211n
                                        : ns3::WIFI_STANDARD_80211a);
  wifi->SetRemoteStationManager(
      "ns3::ConstantRateWifiManager", "DataMode", ns3::StringValue(d.data_mode), "ControlMode",
      ns3::StringValue(d.standard->base_mode), "MaxSsrc", ns3::UintegerValue(d.retry_limit),
      "MaxSlrc", ns3::UintegerValue(d.retry_limit));
  ns3::YansWifiPhyHelper phy;
  phy.SetChannel(make_channel(d.exponent, d.reference_loss));
  phy.Set("TxPowerStart", ns3::DoubleValue(d.tx_power));
  phy.Set("TxPowerEnd", ns3::DoubleValue(d.tx_power));
  if (name == "802.11n") phy.Set("ChannelSettings", ns3::StringValue("{36, 20, BAND_5GHZ, 0}"));
  if (p) return wifi->Install(phy, ns3::NqosWaveMacHelper::Default(), nodes);
  ns3::WifiMacHelper mac;
  mac.SetType("ns3::AdhocWifiMac", "BE_MaxAmpduSize", ns3::UintegerValue(0), "BE_MaxAmsduSize",
              ns3::UintegerValue(0));
  return wifi->Install(phy, mac, nodes);
}

void WifiDesign::build(World& world, const std::vector<int>& senders) const {
  ns3::NodeContainer nodes = world.create_nodes(senders);
  for (std::uint32_t i = 0; i < nodes.GetN(); ++i)
    nodes.Get(i)->AggregateObject(world.place(i, senders, sink));
  ns3::WifiHelper streams_of;  // AssignStreams reads only the devices
  const ns3::NetDeviceContainer devices = install(*this, nodes);
  constexpr std::int64_t kStreamsPerDevice = 16;
  const std::int64_t count = kStreamsPerDevice * static_cast<std::int64_t>(devices.GetN());
  const std::int64_t used = streams_of.AssignStreams(devices, world.streams(count));
  NCOSIM_CHECK(used <= count);
  world.attach_all(devices, senders, false, [&world](int s, const ns3::Ptr<ns3::NetDevice>& d) {
    auto device = ns3::DynamicCast<ns3::WifiNetDevice>(d);
    const bool connected = device->GetMac()->TraceConnectWithoutContext(
                               "DroppedMpdu", ns3::MakeBoundCallback(&dropped_mpdu, &world)) &&
                           device->GetPhy()->TraceConnectWithoutContext(
                               "PhyTxPsduBegin", ns3::MakeBoundCallback(&tx_begin, &world, s)) &&
                           device->GetPhy()->GetState()->TraceConnectWithoutContext(
                               "State", ns3::MakeBoundCallback(&phy_state, &world, s));
    NCOSIM_CHECK(connected);
  });
}
#else
void WifiDesign::build(World&, const std::vector<int>&) const { NCOSIM_CHECK(false); }
#endif

std::shared_ptr<const NetworkDesign> read_wifi(const config::Table& t) {
  const config::KeyReader r(t, wifi_keys());
  auto d = std::make_shared<WifiDesign>();
  const std::string name = r.string("standard");
  for (const Standard& s : standards()) {
    if (name == s.name) d->standard = &s;
  }
  NCOSIM_CHECK(d->standard != nullptr);  // the choice is one of them
  d->data_mode = r.opt_string("data_mode").value_or(d->standard->base_mode);
  const auto& modes = d->standard->modes;
  if (std::find(modes.begin(), modes.end(), d->data_mode) == modes.end()) {
    t.fail("data_mode", fmt::format("expected a data mode of {} ({}), got \"{}\"", name,
                                    fmt::join(modes, ", "), d->data_mode));
  }
  d->tx_power = r.number("tx_power");
  d->retry_limit = static_cast<std::uint32_t>(r.integer("retry_limit"));
  d->exponent = r.number("path_loss_exponent");
  d->reference_loss =
      r.opt_number("reference_loss").value_or(free_space_at_1m(d->standard->carrier_hz));
  if (r.has("sink_position")) d->sink = read_xyz(t, r, "sink_position");
  if (!have_ns3()) t.fail("kind", without_ns3_message());
  return d;
}

}  // namespace

void register_wifi(NetworkRegistry& registry) {
  registry.add("wifi",
               "IEEE 802.11a/g/n ad hoc or 802.11p OCB (ns-3 wifi and wave: DCF, acknowledged "
               "unicast to the sink, constant rate, log-distance path loss): standard, tx_power, "
               "data_mode, retry_limit, sink_position, path_loss_exponent, reference_loss",
               wifi_keys(), read_wifi);
}

}  // namespace ncosim::network
