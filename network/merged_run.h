// network/merged_run.h — a run's networks split by engine (internal to network/): each engine
// gets its own networks and senders, renumbered from 0, and the parts are merged back into one
// NetworkRun whose sender and network indices are the scenario's. With one engine (every shipped
// scenario) the engine's own run is returned as it is.
#pragma once

#include <functional>
#include <memory>
#include <vector>

#include "network/backend.h"

namespace ncosim::network {

// Starts the part of engine `engine`: `networks` are the scenario's indices of its networks, and
// `senders` its senders with Sender::network renumbered into `networks`.
using StartPart = std::function<std::unique_ptr<NetworkRun>(
    const NetworkEngine& engine, const std::vector<std::size_t>& networks,
    const std::vector<Sender>& senders)>;

// The run of `designs` (the scenario's networks) with `senders`, one part per engine in the order
// of their first network.
std::unique_ptr<NetworkRun> start_merged(const std::vector<const NetworkDesign*>& designs,
                                         const std::vector<Sender>& senders,
                                         const StartPart& start);

}  // namespace ncosim::network
