// network/network.h — packet-level networks: the built-in network kinds (ns-3's csma, lr_wpan and
// wifi, network/ns3/), the `network` link kind (a [[link]] that is a node of a [[network]],
// network/network_link.h) and the keys the radio kinds share. The interface every backend
// implements is network/backend.h; a scenario's networks, read and run, are network/networks.h.
#pragma once

#include <array>
#include <string_view>

#include "config/keys.h"
#include "models/link_factory.h"
#include "network/backend.h"

namespace ncosim::network {

void register_networks(NetworkRegistry& registry);
// The `network` link kind (network/network_link.h): a [[link]] that is a node of a [[network]].
void register_network_links(models::LinkRegistry& registry);

// The [x, y, z] (m) of the numbers key `key` of `t` (read through `r`): exit 2 unless it holds
// exactly three numbers.
std::array<double, 3> read_xyz(const config::Table& t, const config::KeyReader& r,
                               std::string_view key);

// The keys every radio kind (lr_wpan, wifi) declares alike: `sink_position` ([x, y, z] m, default
// the origin) and `path_loss_exponent` (log-distance, default 3). Each kind declares its own
// `reference_loss` (its carrier's free space at 1 m).
config::Key sink_position_key();
config::Key path_loss_exponent_key();

}  // namespace ncosim::network
