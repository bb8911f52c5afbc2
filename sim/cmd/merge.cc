// sim/cmd/merge.cc — see sim/cmd/merge.h.
#include "sim/cmd/merge.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <charconv>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <thread>

#include "ncosim_version.h"
#include "sim/analysis/output.h"
#include "sim/analysis/paired.h"
#include "sim/cmd/campaign_meta.h"
#include "sim/cmd/exports.h"
#include "sim/cmd/manifest.h"
#include "sim/cmd/mpi_campaign.h"
#include "sim/files/output_set.h"
#include "sim/present/table_view.h"
#include "sim/run/campaign.h"
#include "sim/run/link_report.h"
#include "sim/run/progress.h"
#include "sim/scenario/resource_limits.h"
#include "sim/store/store.h"

namespace ncosim::sim {

namespace {

// The run stores of a campaign's shards, opened read-only, with their campaign tables.
struct ShardStores {
  std::vector<RunStore> stores;
  std::vector<std::map<std::string, std::string>> metas;
};

// Opens the store of each folder; throws when the output folder is one of them, when one does
// not open or when they are shards of different campaigns.
ShardStores open_shards(const std::string& out, const std::vector<std::string>& dirs) {
  namespace fs = std::filesystem;
  std::error_code ec;
  for (const auto& d : dirs) {
    if (fs::exists(out, ec) && fs::exists(d, ec) && fs::equivalent(out, d, ec)) {
      throw config::ScenarioError(
          fmt::format("merge: the output folder '{}' is also an input", out));
    }
  }
  ShardStores s;
  for (const auto& d : dirs) {
    restore_interrupted_write(d);  // a shard whose last write was interrupted: its previous set
    try {
      s.stores.push_back(RunStore::open(store_path(d), false));
      s.metas.push_back(s.stores.back().meta());
      check_campaign_meta(s.metas.back(), store_path(d));
    } catch (const StoreError& e) {
      throw config::ScenarioError(fmt::format("merge: {}", e.what()));
    }
    const std::string diff = identity_difference(s.metas.front(), s.metas.back(), false);
    if (!diff.empty()) {
      throw config::ScenarioError(
          fmt::format("merge: {} and {} are shards of different campaigns: {} differ(s)",
                      store_path(dirs.front()), store_path(d), diff));
    }
  }
  return s;
}

// The shard holding each (case, run); throws when two shards hold the same one.
std::map<std::pair<std::size_t, std::uint64_t>, std::size_t> run_owners(
    ShardStores& shards, const std::vector<std::string>& dirs, const LoadedScenario& loaded) {
  std::map<std::pair<std::size_t, std::uint64_t>, std::size_t> owner;
  for (std::size_t s = 0; s < shards.stores.size(); ++s) {
    for (std::size_t c = 0; c < loaded.cases.size(); ++c) {
      for (std::uint64_t r : shards.stores[s].done_runs(c)) {
        const auto [it, fresh] = owner.emplace(std::make_pair(c, r), s);
        if (!fresh) {
          throw config::ScenarioError(
              fmt::format("merge: run {} of case {} is in both {} and {} (overlapping shards)", r,
                          c + 1, store_path(dirs[it->second]), store_path(dirs[s])));
        }
      }
    }
  }
  return owner;
}

// Throws naming the first missing runs unless every run of every case has an owner (with
// --target-ci, every run up to --max-runs: the shards run to it and the merge decides).
void check_complete(const std::map<std::pair<std::size_t, std::uint64_t>, std::size_t>& owner,
                    const LoadedScenario& loaded, const TargetRule& rule) {
  std::vector<std::string> missing;
  std::size_t missing_count = 0;
  for (std::size_t c = 0; c < loaded.cases.size(); ++c) {
    const auto runs =
        rule.on() ? rule.max_runs : static_cast<std::uint64_t>(loaded.cases[c].scenario->run.runs);
    for (std::uint64_t r = 0; r < runs; ++r) {
      if (owner.count({c, r}) != 0) continue;
      ++missing_count;
      if (missing.size() < 5)
        missing.push_back(loaded.cases.size() > 1 ? fmt::format("case {} run {}", c + 1, r)
                                                  : fmt::format("run {}", r));
    }
  }
  if (missing_count > 0) {
    std::string list;
    for (std::size_t i = 0; i < missing.size(); ++i) list += (i ? ", " : "") + missing[i];
    throw config::ScenarioError(fmt::format(
        "merge: {} run(s) missing from the given stores (first: {}); merge every shard, "
        "each complete (`ncosim run ... --shard I/N --resume` finishes one)",
        missing_count, list));
  }
}

// The campaign table of the merged store: the first shard's, unsharded, with the shards' wall
// time summed and the folders it was merged from.
std::map<std::string, std::string> merged_meta(
    const std::vector<std::map<std::string, std::string>>& metas,
    const std::vector<std::string>& dirs) {
  auto meta = metas.front();
  meta["shard"] = "";
  meta.erase("store");
  double wall = 0.0;
  for (const auto& m : metas) {
    try {
      wall += std::stod(m.at("wall_seconds"));
    } catch (...) {
    }
  }
  meta["wall_seconds"] = fmt::format("{:.17g}", wall);
  meta["merged_from"] = json_text(dirs);
  meta["stopped"] = "";
  return meta;
}

// Case c of every shard into the merged store: estimator names, runs with their link
// counters, and the timing of the first shard that measured it.
void merge_case(ShardStores& shards, RunStore& merged, const Scenario& sc, std::size_t c) {
  std::vector<std::string> names;
  for (const auto& e : sc.estimators) names.push_back(e.name);
  merged.put_estimators(c, names);
  std::vector<StoredRun> batch;
  for (auto& store : shards.stores) {
    std::map<std::uint64_t, RunLinks> links;
    for (auto& [run, l] : store.load_case_links(c)) links.emplace(run, std::move(l));
    for (auto& [run, m] : store.load_case(c)) {
      StoredRun sr{c, run, std::move(m), std::nullopt};
      if (auto it = links.find(run); it != links.end()) sr.links = std::move(it->second);
      batch.push_back(std::move(sr));
    }
  }
  merged.put_runs(batch);
  for (auto& store : shards.stores) merged.add_curve(c, store.curve(c));
  std::vector<double> ns(sc.estimators.size(), std::nan(""));
  for (auto& store : shards.stores) {
    const auto t = store.timing(c, sc.estimators.size());
    bool any = false;
    for (double v : t) any = any || std::isfinite(v);
    if (any) {
      ns = t;
      break;
    }
  }
  merged.put_timing(c, ns);
}

}  // namespace

int cmd_merge(const std::string& out, const std::vector<std::string>& dirs, bool replace,
              const std::string& command_line) {
  if (dirs.empty()) throw config::ScenarioError("merge: expected at least one shard folder");
  ShardStores shards = open_shards(out, dirs);
  LoadedScenario loaded;
  try {
    loaded = reload(shards.metas.front(), store_path(dirs.front()));
    for (std::size_t i = 0; i < shards.stores.size(); ++i) {
      shards.stores[i].verify(loaded.cases.size(), run_limit(loaded, shards.metas[i]));
    }
  } catch (const StoreError& e) {
    throw config::ScenarioError(fmt::format("merge: {}", e.what()));
  }
  // Every (case, run) exactly once.
  const auto owner = run_owners(shards, dirs, loaded);
  check_complete(owner, loaded, target_of(shards.metas.front(), loaded));
  const OutputFolderLock folder_lock(out);  // sim/files/output_set.h
  const auto meta = merged_meta(shards.metas, dirs);
  // The rule of `run --out` (sim/cmd/exports.h): the folder's runs, and those of an unfinished
  // campaign beside it, are replaced only when every one comes back, or with --replace.
  check_folder_replace(FolderWrite{"merge", out, &meta, "the merged shards", loaded.cases.size(),
                                   [&](std::size_t c, std::uint64_t r) {
                                     return owner.count({c, r}) != 0;
                                   },
                                   replace, true});
  prepare_output_dir(out);
  // Built beside the folder and swapped in with the exports (export_and_install).
  note_replaced_partial(out, partial_store_path(out));
  RunStore merged = RunStore::create(partial_store_path(out), meta);
  try {
    for (std::size_t c = 0; c < loaded.cases.size(); ++c)
      merge_case(shards, merged, *loaded.cases[c].scenario, c);
    for (auto& store : shards.stores) {
      for (const auto& [name, content] : store.artifacts()) merged.put_artifact(name, content);
    }
  } catch (...) {  // a write failure (the shards were verified before): no partial store stays
    const std::string partial = merged.path();
    merged = RunStore();
    remove_store_files(partial);
    throw;
  }
  for (auto& store : shards.stores) store.close();
  ExportInfo info;
  info.command_line = command_line;
  export_and_install(loaded, merged, out, info);
  std::cout << fmt::format("{} store(s) merged: {} runs x {} case(s); results in {}/\n",
                           dirs.size(), owner.size(), loaded.cases.size(), out);
  return 0;
}

}  // namespace ncosim::sim
