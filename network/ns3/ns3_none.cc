// network/ns3/ns3_none.cc — a build without ns-3: the ns-3 kinds are read and documented, but a
// scenario that uses one is refused when read (network/ns3/ns3_network.h), so no run starts.
#include <stdexcept>

#include "network/ns3/ns3_network.h"

namespace ncosim::network {

namespace {

class Ns3Missing final : public NetworkEngine {
 public:
  std::string name() const override { return "ns-3"; }
  std::unique_ptr<NetworkRun> start(const std::vector<const NetworkDesign*>&,
                                    const std::vector<Sender>&, std::uint64_t,
                                    std::uint64_t) const override {
    throw std::logic_error(without_ns3_message());
  }
};

}  // namespace

const NetworkEngine& ns3_engine() {
  static const Ns3Missing engine;
  return engine;
}

bool have_ns3() { return false; }

}  // namespace ncosim::network
