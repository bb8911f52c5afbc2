// sim/cmd/campaign_meta.h — the campaign table of a run store (runs.sqlite): what a new store
// records about its campaign (scenario, hashes, overrides, shard, --target-ci), the checks that a
// store belongs to the campaign being resumed or merged, the scenario reloaded from it, and the
// rules of --target-ci and --max-runs that decide how many runs a case gets.
#pragma once

#include <cstdint>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "sim/run/campaign.h"
#include "sim/scenario/scenario.h"
#include "sim/store/store.h"

namespace ncosim::sim {

struct Shard {
  std::uint64_t index = 0;  // 0-based
  std::uint64_t count = 1;
  bool owns(std::uint64_t run) const { return run % count == index; }
};

// "I/N" with 1 <= I <= N: throws ScenarioError naming --shard otherwise.
std::string json_text(const nlohmann::json& j);

// The campaign table of a new store.
std::map<std::string, std::string> campaign_meta(const LoadedScenario& loaded,
                                                 const RunOverrides& ov, const std::string& shard);

// Empty when `a` and `b` are the same campaign; else what differs.
std::string identity_difference(const std::map<std::string, std::string>& a,
                                const std::map<std::string, std::string>& b, bool with_shard);

// Checks every field of a store's campaign table that the commands read, so that a damaged or
// hand-edited table is refused with the field's name (StoreError) instead of a bare parser
// exception or a silently different campaign.
void check_campaign_meta(const std::map<std::string, std::string>& meta, const std::string& path);

RunOverrides overrides_of(const std::map<std::string, std::string>& meta);

// The scenario of a store, rebuilt from its text (designs included); `path` names the store in
// messages. The campaign table is checked first (check_campaign_meta), then that the text gives
// the stored hash, runs, periods, seed and cases, and that every input file it reads still has the
// content the campaign read. Throws StoreError on a damaged store, ScenarioError otherwise.
LoadedScenario reload(const std::map<std::string, std::string>& meta, const std::string& path);

Shard shard_of(const std::map<std::string, std::string>& meta);

std::uint64_t owned_runs(const Scenario& sc, const Shard& shard);

// --target-ci: runs in fixed batches of run.runs in run-index order until every row's relative
// 95 % CI half-width of mse is at most `rel`, or --max-runs. The decision depends on the runs
// 0 .. n-1 alone, so it is the same for any threads, shards or ranks.
struct TargetRule {
  double rel = 0.0;
  std::uint64_t max_runs = 0;
  std::uint64_t batch = 0;
  bool on() const { return rel > 0.0; }
};

TargetRule target_of(const std::map<std::string, std::string>& meta, const LoadedScenario& loaded);

struct TargetDecision {
  bool decided = false;
  std::uint64_t runs = 0;              // runs per case the exports use (when decided)
  std::string reason;                  // "target_ci" or "max_runs"
  std::vector<std::vector<char>> met;  // [case][estimator]: 1 met, 0 not met, 2 excluded
};

TargetDecision decide_target(const LoadedScenario& loaded,
                             const std::vector<CampaignResult>& results, const TargetRule& rule);

Shard parse_shard(const std::string& text);

}  // namespace ncosim::sim
