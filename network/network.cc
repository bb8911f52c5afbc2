// network/network.cc — the network registry's built-ins and the `network` link kind: a [[link]]
// that is a node of a [[network]] (network/network.h).
#include "network/network.h"

#include <fmt/format.h>

#include "kernel/rng.h"

namespace ncosim::network {

void register_csma(NetworkRegistry& registry);  // network/csma.cc

void register_lr_wpan(NetworkRegistry& registry);  // network/lr_wpan.cc

void register_wifi(NetworkRegistry& registry);  // network/wifi.cc

void register_networks(NetworkRegistry& registry) {
  register_csma(registry);
  register_lr_wpan(registry);
  register_wifi(registry);
}

std::uint32_t ns3_seed(std::uint64_t seed) {
  auto rng = kernel::make_stream(seed, 0, kernel::stream_id(kernel::StreamKind::kNetwork, 0));
  return 1U + static_cast<std::uint32_t>(rng() % 4294967086ULL);  // MRG32k3a: below m1
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

std::string without_ns3_message() {
  return "this ncosim was built without ns-3, which packet-level networks need (on Debian 12: "
         "apt-get install libns3-dev libgsl-dev, then configure and build again)";
}

}  // namespace ncosim::network
