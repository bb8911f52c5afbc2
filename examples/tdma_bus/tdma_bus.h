// tdma_bus.h — the `tdma_bus` network kind: a time-division bus written against ncosim's network
// interface alone (network/backend.h). Time is cut into frames of `slots` slots of `slot` seconds;
// node i (the i-th node of the network: its links' nodes in scenario order) owns slot i mod
// slots of every frame. A packet handed to a node waits in its queue (at most `queue` packets not
// yet on the air; one more is dropped at once, cause queue); at the start of each of its slots the
// node puts its oldest packet on the air, and the sink receives it at the slot's end. Nothing is
// random: every fate follows from the send times by hand (scenario.toml works one out).
#pragma once

#include "network/backend.h"

void register_tdma_bus(ncosim::network::NetworkRegistry& registry);
