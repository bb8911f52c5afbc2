// network/network.cc — the network registry's built-ins and the keys the radio kinds share
// (network/network.h).
#include "network/network.h"

#include <fmt/format.h>

#include "network/ns3/ns3_network.h"

namespace ncosim::network {

void register_networks(NetworkRegistry& registry) {
  register_csma(registry);
  register_lr_wpan(registry);
  register_wifi(registry);
}

std::array<double, 3> read_xyz(const config::Table& t, const config::KeyReader& r,
                               std::string_view key) {
  const std::vector<double> p = r.numbers(key);
  if (p.size() != 3) t.fail(key, fmt::format("expected [x, y, z] (m), got {} numbers", p.size()));
  return {p[0], p[1], p[2]};
}

config::Key sink_position_key() {
  return config::Key::numbers("sink_position")
      .optional("[0, 0, 0]")
      .entries(3)
      .unit("m")
      .help("[x, y, z] of the sink, the estimators' node");
}

config::Key path_loss_exponent_key() {
  return config::Key::number("path_loss_exponent")
      .range(1.0, 8.0)
      .says("an exponent in 1..8")
      .or_default(3.0)
      .help("log-distance path loss: L(d) = reference_loss + 10 exponent log10(d / 1 m)");
}

}  // namespace ncosim::network
