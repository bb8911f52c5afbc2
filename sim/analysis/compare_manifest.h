// sim/analysis/compare_manifest.h — a folder as `ncosim compare` reads it (manifest.json, runs.csv,
// summary.csv), and what it reads of two folders' manifest.json (and run stores) to decide whether
// they ran the same scenario, and to name, one line each, what differs. The scenario is the same
// when the text and the --set assignments are (scenario_text_hash): other --runs, --periods or
// --seed are other campaigns of the same scenario, compared without
// --allow-scenario-change (paired or not by seed, sim/analysis/compare.cc). Docs:
// results/README.md, "manifest.json" and "compare.csv and compare.md".
#pragma once

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "sim/analysis/run_folder.h"

namespace ncosim::sim {

// Fills f.fields, f.text_hash and f.text from the parsed manifest.json and, when the folder holds
// a readable runs.sqlite, from its campaign table (the text the campaign ran; the text hash of a
// manifest written before scenario_text_hash). A missing or unreadable store is not an error.
void read_folder_identity(const nlohmann::json& manifest, RunFolder& f);

// Whether the two folders ran the same scenario text and --set assignments: their text hashes
// when both are known, else (a folder of an older ncosim without a store) their scenario_hash.
bool same_scenario_text(const RunFolder& base, const RunFolder& fresh);

// Every manifest field that differs, "field: BASE -> NEW" (long values shortened; each input
// file on its own line; "scenario text: line N: ..." when both texts are known), in field order.
// Fields of how and when a campaign ran (command_line, date, threads, ...) are left out.
std::vector<std::string> manifest_differences(const RunFolder& base, const RunFolder& fresh);

// The first line where two texts differ, "line N: `a` -> `b`" (shortened); "" when equal.
std::string first_differing_line(const std::string& a, const std::string& b);

// Reads DIR/manifest.json and DIR/runs.csv for `metric`. Throws CompareInputError.
RunFolder read_run_folder(const std::string& dir, const std::string& metric);
// Fills each row's status and expected_status from DIR/summary.csv (left empty when the file, a
// column or the row is missing: folders of older versions). Throws CompareInputError on a
// malformed file. Divergence in NEW only is "worse" unless NEW's row expects `diverged`; a
// status that changed is said in the row's note, "(unexpected)" when NEW's row does not expect it.
void read_row_statuses(RunFolder& f);

// "estimator \"E\"", or "case KEY=VALUE, ..., estimator \"E\"" with sweeps: a row in messages.
std::string row_text(const std::vector<std::string>& keys, const RunFolder::Row& r);

}  // namespace ncosim::sim
