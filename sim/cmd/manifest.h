// sim/cmd/manifest.h — manifest.json of a campaign: what ran (scenario, hashes, overrides, seed,
// runs, periods), with which ncosim (version, commit), when and how (command line, threads, wall
// time).
#pragma once

#include <nlohmann/json.hpp>
#include <string>

#include "sim/scenario/scenario_types.h"

namespace ncosim::sim {

// manifest.json of a campaign (scenario, hash, overrides, seed, version, commit, date, ...).
nlohmann::json campaign_manifest(const LoadedScenario& loaded, const std::string& command_line,
                                 int threads, double wall_seconds);

// The current UTC time as ISO 8601 (2026-01-31T12:00:00Z).
std::string utc_now();

}  // namespace ncosim::sim
