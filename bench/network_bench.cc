// bench/network_bench.cc — what the co-simulation of a packet-level network costs (bench/README.md,
// "ns-3 networks"): the same packets on the same network, (a) a bare ns-3 program (the network
// built with ns-3's helpers, every send scheduled up front, one Simulator::Run) and (b) ncosim's
// session (network/networks.h: the network built by its kind, ns-3 advanced in lockstep to every
// period boundary, each packet's fate collected), alternating in one process so that a load change
// on a shared machine hits both alike. Counters: bare_s, session_s (median seconds of one
// campaign of kPeriods periods), ratio (median of session / bare, per delivered packet),
// packets_per_s (session), same_outcome (1 when both delivered the same number of packets).
// Built with ns-3 only (NCOSIM_NS3).
#include <benchmark/benchmark.h>

#if NCOSIM_HAVE_NS3
#include <ns3/boolean.h>
#include <ns3/constant-position-mobility-model.h>
#include <ns3/csma-helper.h>
#include <ns3/double.h>
#include <ns3/lr-wpan-helper.h>
#include <ns3/lr-wpan-net-device.h>
#include <ns3/node-container.h>
#include <ns3/packet.h>
#include <ns3/propagation-delay-model.h>
#include <ns3/propagation-loss-model.h>
#include <ns3/rng-seed-manager.h>
#include <ns3/simulator.h>
#include <ns3/single-model-spectrum-channel.h>
#include <ns3/string.h>
#include <ns3/uinteger.h>
#include <ns3/wifi-helper.h>
#include <ns3/wifi-mac-helper.h>
#include <ns3/yans-wifi-channel.h>
#include <ns3/yans-wifi-helper.h>
#include <toml++/toml.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "config/config.h"
#include "network/network.h"
#include "network/networks.h"
#include "network/ns3/ns3_network.h"
#include "sim/scenario/registries.h"

namespace ncosim {
namespace {

using Clock = std::chrono::steady_clock;
enum class Kind { kCsma, kLrWpan, kWifi };
constexpr std::int64_t kPeriodNs = 20'000'000;  // 20 ms
constexpr int kPeriods = 500;
constexpr std::uint32_t kBytes = 24;

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n == 0 ? 0.0 : (n % 2 == 1 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]));
}

// Node i of k on a circle of 20 m around the sink.
double coordinate(int i, int k, bool y) {
  const double a = 2.0 * M_PI * i / k;
  return 20.0 * (y ? std::sin(a) : std::cos(a));
}

std::int64_t g_received = 0;
bool count(ns3::Ptr<ns3::NetDevice>, ns3::Ptr<const ns3::Packet>, std::uint16_t,
           const ns3::Address&) {
  ++g_received;
  return true;
}
void send(ns3::Ptr<ns3::NetDevice> d, ns3::Address to) {
  d->Send(ns3::Create<ns3::Packet>(kBytes), to, 0x88B5);
}

// The wifi kind's defaults (network/ns3/wifi.cc): 802.11a at 6 Mb/s, 16 dBm, log-distance loss of
// exponent 3 from free space at 1 m at 5.18 GHz, ad hoc stations.
ns3::NetDeviceContainer bare_wifi(const ns3::NodeContainer& nodes, int k) {
  for (std::uint32_t i = 0; i < nodes.GetN(); ++i) {
    auto m = ns3::CreateObject<ns3::ConstantPositionMobilityModel>();
    if (i > 0)
      m->SetPosition(ns3::Vector(coordinate(static_cast<int>(i) - 1, k, false),
                                 coordinate(static_cast<int>(i) - 1, k, true), 0.0));
    nodes.Get(i)->AggregateObject(m);
  }
  auto loss = ns3::CreateObject<ns3::LogDistancePropagationLossModel>();
  loss->SetAttribute("Exponent", ns3::DoubleValue(3.0));
  loss->SetAttribute("ReferenceLoss",
                     ns3::DoubleValue(20.0 * std::log10(4.0 * M_PI * 5.18e9 / 299'792'458.0)));
  auto channel = ns3::CreateObject<ns3::YansWifiChannel>();
  channel->SetPropagationLossModel(loss);
  channel->SetPropagationDelayModel(ns3::CreateObject<ns3::ConstantSpeedPropagationDelayModel>());
  ns3::WifiHelper wifi;
  wifi.SetStandard(ns3::WIFI_STANDARD_80211a);
  wifi.SetRemoteStationManager("ns3::ConstantRateWifiManager", "DataMode",
                               ns3::StringValue("OfdmRate6Mbps"), "ControlMode",
                               ns3::StringValue("OfdmRate6Mbps"));
  ns3::YansWifiPhyHelper phy;
  phy.SetChannel(channel);
  phy.Set("TxPowerStart", ns3::DoubleValue(16.0));
  phy.Set("TxPowerEnd", ns3::DoubleValue(16.0));
  ns3::WifiMacHelper mac;
  mac.SetType("ns3::AdhocWifiMac", "BE_MaxAmpduSize", ns3::UintegerValue(0), "BE_MaxAmsduSize",
              ns3::UintegerValue(0));
  const ns3::NetDeviceContainer devices = wifi.Install(phy, mac, nodes);
  wifi.AssignStreams(devices, 0);
  return devices;
}

// (a) bare ns-3: the same network as the kind's build(), all sends scheduled, one run.
double bare(Kind kind, int k) {
  const bool wpan = kind == Kind::kLrWpan;
  ns3::RngSeedManager::SetSeed(network::ns3_seed(7));  // as the session's
  ns3::RngSeedManager::SetRun(0);
  const auto start = Clock::now();
  g_received = 0;
  ns3::NodeContainer nodes;
  nodes.Create(static_cast<std::uint32_t>(k + 1));
  ns3::NetDeviceContainer devices;
  std::unique_ptr<ns3::LrWpanHelper> helper;
  if (wpan) {
    auto channel = ns3::CreateObject<ns3::SingleModelSpectrumChannel>();
    channel->AddPropagationLossModel(ns3::CreateObject<ns3::LogDistancePropagationLossModel>());
    channel->SetPropagationDelayModel(ns3::CreateObject<ns3::ConstantSpeedPropagationDelayModel>());
    helper = std::make_unique<ns3::LrWpanHelper>();
    helper->SetChannel(channel);
    devices = helper->Install(nodes);
    helper->AssociateToPan(devices, 1);
    for (std::uint32_t i = 0; i < devices.GetN(); ++i) {
      auto m = ns3::CreateObject<ns3::ConstantPositionMobilityModel>();
      if (i > 0)
        m->SetPosition(ns3::Vector(coordinate(static_cast<int>(i) - 1, k, false),
                                   coordinate(static_cast<int>(i) - 1, k, true), 0.0));
      ns3::DynamicCast<ns3::LrWpanNetDevice>(devices.Get(i))->GetPhy()->SetMobility(m);
      devices.Get(i)->SetAttribute("UseAcks", ns3::BooleanValue(true));
    }
    helper->AssignStreams(devices, 0);
  } else if (kind == Kind::kWifi) {
    devices = bare_wifi(nodes, k);
  } else {
    ns3::CsmaHelper csma;
    csma.SetChannelAttribute("DataRate", ns3::DataRateValue(ns3::DataRate(1'000'000)));
    devices = csma.Install(nodes);
    csma.AssignStreams(devices, 0);
  }
  devices.Get(0)->SetReceiveCallback(ns3::MakeCallback(&count));
  for (int p = 0; p < kPeriods; ++p) {
    for (int i = 1; i <= k; ++i)
      ns3::Simulator::Schedule(ns3::NanoSeconds(p * kPeriodNs), &send,
                               devices.Get(static_cast<std::uint32_t>(i)),
                               devices.Get(0)->GetAddress());
  }
  ns3::Simulator::Run();
  ns3::Simulator::Destroy();
  return std::chrono::duration<double>(Clock::now() - start).count();
}

// (b) ncosim's session on the same network, in lockstep with the period boundaries.
double session(Kind kind, int k, std::int64_t& delivered_out) {
  static std::vector<toml::table> docs;
  docs.push_back(toml::parse(kind == Kind::kLrWpan ? "kind = \"lr_wpan\"\n"
                             : kind == Kind::kWifi
                                 ? "kind = \"wifi\"\n"
                                 : "kind = \"csma\"\nrate = 1e6\ndelay = 1e-6\n"));
  const config::Table t(docs.back(), "network[0]", "bench.toml");
  const auto design = sim::network_registry().lookup(t, "kind", "").factory(t);
  std::vector<network::Sender> senders;
  for (int i = 0; i < k; ++i)
    senders.push_back(
        network::Sender{0, kBytes, coordinate(i, k, false), coordinate(i, k, true), 0.0});
  const auto start = Clock::now();
  auto s = network::start_here({design.get()}, senders, 7, 0);
  std::vector<network::Fate> fates;
  std::int64_t id = 0;
  for (int p = 0; p < kPeriods; ++p) {
    for (int i = 0; i < k; ++i) s->send(i, static_cast<std::uint64_t>(id++), p * kPeriodNs);
    s->advance_to(p * kPeriodNs, fates);
    for (const auto& f : fates) delivered_out += f.drop == network::Drop::kNone;
    fates.clear();
  }
  s->advance_to(std::int64_t{kPeriods + 50} * kPeriodNs, fates);
  for (const auto& f : fates) delivered_out += f.drop == network::Drop::kNone;
  s.reset();
  return std::chrono::duration<double>(Clock::now() - start).count();
}

void run(benchmark::State& state, Kind kind) {
  const int k = static_cast<int>(state.range(0));
  std::vector<double> b, c, ratio;
  std::int64_t delivered = 0;
  for (auto _ : state) {
    const double tb = bare(kind, k);
    delivered = 0;
    const double tc = session(kind, k, delivered);
    b.push_back(tb);
    c.push_back(tc);
    // Per delivered packet: with contention, the session's sends enter ns-3's queue after the
    // events of the previous period boundary, the bare program's all at the start, so packets
    // that meet at one instant may be ordered differently and the two realisations differ.
    ratio.push_back((tc / static_cast<double>(std::max<std::int64_t>(delivered, 1))) /
                    (tb / static_cast<double>(std::max<std::int64_t>(g_received, 1))));
  }
  state.counters["bare_s"] = median(b);
  state.counters["session_s"] = median(c);
  state.counters["ratio"] = median(ratio);
  state.counters["packets_per_s"] = static_cast<double>(k) * kPeriods / median(c);
  // The same packets on the same network: the same deliveries (1), else the comparison is void.
  state.counters["same_outcome"] = g_received == delivered ? 1.0 : 0.0;
  state.counters["delivered"] = static_cast<double>(delivered);
}

void BM_NetworkLrWpanStar(benchmark::State& state) { run(state, Kind::kLrWpan); }
void BM_NetworkCsmaBus(benchmark::State& state) { run(state, Kind::kCsma); }
void BM_NetworkWifiAdhoc(benchmark::State& state) { run(state, Kind::kWifi); }
BENCHMARK(BM_NetworkLrWpanStar)
    ->Arg(1)
    ->Arg(4)
    ->Arg(8)
    ->Iterations(9)
    ->Unit(benchmark::kMillisecond);
BENCHMARK(BM_NetworkCsmaBus)->Arg(1)->Arg(4)->Arg(8)->Iterations(9)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_NetworkWifiAdhoc)
    ->Arg(1)
    ->Arg(4)
    ->Arg(8)
    ->Iterations(9)
    ->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace ncosim
#endif
