// sim/cmd/exports.h — the exports of a run store (summary.csv, summary.md, runs.csv, links.csv,
// transmissions.csv, confusion.csv, error_curve.csv, trajectory.csv, manifest.json), derived from
// the stored runs through the functions of sim/analysis/output.h and installed as one result
// set; `ncosim export`.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "sim/cmd/campaign_meta.h"
#include "sim/present/table_view.h"
#include "sim/run/campaign.h"
#include "sim/scenario/scenario.h"
#include "sim/store/store.h"

namespace ncosim::sim {

// The link counters of every stored run, into each case's CampaignResult::link_runs (aligned
// with its runs). Complete when every run has them; else link_runs are left empty.
struct LinkCoverage {
  bool complete = true;
  std::size_t present = 0, missing = 0;
};

LinkCoverage load_link_runs(const RunStore& store, std::vector<CampaignResult>& results);

struct ExportInfo {
  std::string command_line;
  std::string stopped;  // why the campaign stopped early ("" when it did not)
  std::vector<std::string>* not_ok =
      nullptr;               // receives "case, \"estimator\": status" of rows not as expected
  bool* complete = nullptr;  // receives manifest.json's `complete`
  const TableRequest* table =
      nullptr;  // `run`: the markdown out-parameter receives its stdout table
};

// The stored error curve of case c restricted to the runs the exports use: runs that the stored
// curve lacks (a campaign killed between committing its runs and its curve) are simulated again
// (the realisations are a function of the seed and run index); a curve that holds runs beyond
// them (--target-ci's stopping point) is rebuilt from those runs alone.
ErrorCurve error_curve_for(const LoadedScenario& loaded, const RunStore& store, std::size_t c,
                           const CampaignResult& res);

// Every export of the store, built by the functions of sim/analysis/output.h from the stored runs.
std::vector<std::pair<std::string, std::string>> derive_exports(const LoadedScenario& loaded,
                                                                const RunStore& store,
                                                                const ExportInfo& info,
                                                                std::string* markdown);

// Before a new store replaces an unfinished campaign's store beside the folder: says so.
void note_replaced_partial(const std::string& out, const std::string& partial);

// Derives the exports of a store built beside the folder (`partial`), finishes it (checkpointed,
// one file), then swaps the exports and the store in as one set and removes the partial store's
// name. Until the swap the folder keeps its previous set, store included.
std::string export_and_install(const LoadedScenario& loaded, RunStore& store,
                               const std::string& out, const ExportInfo& info);

// The largest run index + 1 that a store of this campaign may hold.
std::uint64_t run_limit(const LoadedScenario& loaded,
                        const std::map<std::string, std::string>& meta);

// A partial store that is the very file of the set's runs.sqlite was left by a kill after the
// swap and before its name was removed: the campaign it holds is finished, so the name goes.
void settle_partial(const std::string& out);

// A command about to write a campaign's store into the folder `out` (export --out, merge).
struct FolderWrite {
  std::string command;                             // "export", "merge": the message's prefix
  std::string out;                                 // the folder written
  const std::map<std::string, std::string>* meta;  // the campaign table of the store written
  std::string source;                              // what the store written is, for messages
  std::size_t cases = 0;
  std::function<bool(std::size_t, std::uint64_t)> holds;  // whether it holds (case, run)
  bool replace = false;                                   // --replace
  bool with_partial = false;  // it also replaces the unfinished store beside the folder
};

// The rule of `run --out` for every command that writes a folder: refuses (ScenarioError, exit 2,
// nothing written) to replace a store of `out` (and, with_partial, the unfinished one beside it)
// that holds runs of a different campaign or runs the new store lacks, unless --replace (then
// says what it replaces). A damaged store, or one whose every run comes back, is replaced.
void check_folder_replace(const FolderWrite& w);

// Re-derives every export of the store in `dir` into `out` (default: `dir`); `replace`: --replace.
int cmd_export(const std::string& dir, const std::string& out, bool replace,
               const std::string& command_line);

}  // namespace ncosim::sim
