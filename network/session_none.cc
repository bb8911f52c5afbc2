// network/session_none.cc — a build without ns-3: the network kinds are read and documented, but
// a scenario that uses one is refused when read (network/network.h), so no session starts.
#include <stdexcept>

#include "network/network.h"

namespace ncosim::network {

std::unique_ptr<Session> Session::start(const std::vector<std::shared_ptr<const NetworkDesign>>&,
                                        const std::vector<Sender>&, std::uint64_t, std::uint64_t) {
  throw std::logic_error(without_ns3_message());
}

bool have_ns3() { return false; }

}  // namespace ncosim::network
