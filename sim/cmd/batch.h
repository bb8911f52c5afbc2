// sim/cmd/batch.h — campaigns on the command line: `ncosim run` with its run store (runs.sqlite),
// SIGINT/SIGTERM, --resume and --shard; `ncosim export` and `ncosim merge`. Every export
// (summary.csv, summary.md, runs.csv, transmissions.csv, confusion.csv, trajectory.csv) is
// derived from the store through the functions of sim/analysis/output.h.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "sim/cmd/campaign_meta.h"
#include "sim/cmd/exports.h"
#include "sim/cmd/merge.h"
#include "sim/run/progress.h"
#include "sim/scenario/scenario.h"

namespace ncosim::sim {

struct RunCommand {
  std::string file;
  std::string out;  // resolved output folder
  std::vector<std::string> sets;
  RunOverrides overrides;
  int threads = 0;
  bool trace = false;
  bool quiet = false;
  bool resume = false;
  bool replace = false;  // --replace: replace a store of a different or unfinished campaign
  bool timing = true;    // false: --no-timing
  std::string shard;     // "I/N" or empty
  std::optional<double> target_ci;  // --target-ci REL
  std::int64_t max_runs = 0;        // --max-runs N
  std::string command_line;
  std::vector<std::string>
      columns;         // --columns: the summary.csv columns on stdout (sim/present/table_view.h)
  std::string format;  // --format md|csv|json ("" = the table fitted to 120 columns)
  bool fail_on_status = false;  // exit kExitFlagged when a row's status is not its expected one
  // Set by an embedding program (sim/cmd/cli.h CliHooks): the progress goes to it, not to stderr.
  CampaignProgress::Observer progress_observer;
  bool second_signal_aborts = true;  // false when embedded: a signal only stops the campaign
};

// Exit status of a command that completed but whose result is flagged (`run --fail-on-status`
// with a row not ok, `codesign` with a status not ok).
inline constexpr int kExitFlagged = 3;

int cmd_run_campaign(const RunCommand& cmd);
}  // namespace ncosim::sim
