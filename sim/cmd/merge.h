// sim/cmd/merge.h — `ncosim merge OUT SHARD...`: the run stores of a campaign's shards combined
// into one store, then exported (sim/cmd/exports.h).
#pragma once

#include <string>
#include <vector>

namespace ncosim::sim {

// Combines the stores of `dirs` (shards of one campaign) into `out`, then exports.
int cmd_merge(const std::string& out, const std::vector<std::string>& dirs,
              const std::string& command_line);

}  // namespace ncosim::sim
