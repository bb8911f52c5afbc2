// network/ns3/ns3_kinds.cc — what every ns-3 kind shares, with or without ns-3 in the build
// (network/ns3/ns3_network.h).
#include "kernel/rng.h"
#include "network/ns3/ns3_network.h"

namespace ncosim::network {

const NetworkEngine& Ns3Network::engine() const { return ns3_engine(); }

std::uint32_t ns3_seed(std::uint64_t seed) {
  auto rng = kernel::make_stream(seed, 0, kernel::stream_id(kernel::StreamKind::kNetwork, 0));
  return 1U + static_cast<std::uint32_t>(rng() % 4294967086ULL);  // MRG32k3a: below m1
}

std::string without_ns3_message() {
  return "this ncosim was built without ns-3, which packet-level networks need (on Debian 12: "
         "apt-get install libns3-dev libgsl-dev, then configure and build again)";
}

}  // namespace ncosim::network
