// sim/cmd/merge.h — `ncosim merge OUT SHARD...`: the run stores of a campaign's shards combined
// into one store, then exported (sim/cmd/exports.h).
#pragma once

#include <string>
#include <vector>

namespace ncosim::sim {

// Combines the stores of `dirs` (shards of one campaign) into `out`, then exports; `replace`:
// --replace (a folder holding other runs is refused without it: check_folder_replace).
int cmd_merge(const std::string& out, const std::vector<std::string>& dirs, bool replace,
              const std::string& command_line);

}  // namespace ncosim::sim
