// network/ns3/ns3_network.h — the ns-3 backend (internal to network/): its kinds (csma, lr_wpan,
// wifi) are NetworkDesigns that build their part of a run's ns-3 world (network/ns3/world.h),
// simulated by one engine whose runs each need a process of their own (one ns-3 simulator per
// process). The kinds and their keys are always built (read, listed and documented the same with
// or without ns-3); a build without ns-3 refuses a scenario that uses one, naming what to install.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "network/backend.h"

namespace ncosim::network {

class World;  // one run's ns-3 simulation (network/ns3/world.h; builds with ns-3 only)

// Every ns-3 kind.
class Ns3Network : public NetworkDesign {
 public:
  const NetworkEngine& engine() const final;
  // Adds this network to the run's world: the sink, then one node per sender (`senders` are the
  // world's sender indices attached to this network, in scenario order), then the transmitters of
  // the downlink senders (Sender::downlink) at the sink's position, in the same order.
  virtual void build(World& world, const std::vector<int>& senders) const = 0;
};

// The ns-3 engine (network/ns3/ns3_engine.cc; ns3_none.cc without ns-3).
const NetworkEngine& ns3_engine();

// The seed of ns-3's generator for campaign seed `seed` (a run is its sub-stream): in
// 1..2^32 - 210.
std::uint32_t ns3_seed(std::uint64_t seed);

// True when this build has ns-3 (NCOSIM_HAVE_NS3): else the kinds' readers refuse.
bool have_ns3();
// The message of a build without ns-3 ("this ncosim was built without ns-3 ...").
std::string without_ns3_message();

void register_csma(NetworkRegistry& registry);     // network/ns3/csma.cc
void register_lr_wpan(NetworkRegistry& registry);  // network/ns3/lr_wpan.cc
void register_wifi(NetworkRegistry& registry);     // network/ns3/wifi.cc

}  // namespace ncosim::network
