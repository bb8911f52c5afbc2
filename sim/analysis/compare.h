// sim/analysis/compare.h — `ncosim compare BASE NEW`: two output folders of the same scenario
// compared row by row (sweep case, estimator) on one per-run metric of runs.csv, as a CI gate. Runs
// are matched by (seed, run index): where both folders ran the same seed the test is paired on the
// runs they share (common random numbers), otherwise Welch's unpaired test. Folders of the same
// scenario text and --set (scenario_text_hash) compare whatever their
// --runs, --periods or --seed; another text or other inputs need --allow-scenario-change. Every
// manifest field that differs is named, one line each (sim/analysis/compare_manifest.h).
// A row is "worse" when its metric is significantly above (1 + tolerance) times the base
// (one-sided test at level alpha, Holm-corrected over the rows), "better" when significantly
// below (1 - tolerance) times it, "unchanged" otherwise, "not comparable" when no test applies.
// Bad input (unreadable or malformed files, a metric cell that is not a finite number >= 0,
// different scenarios, missing rows) throws CompareInputError naming the FILE (and LINE) (exit 2).
// runs.csv is streamed: memory follows the runs of the metric, not the file's size.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "config/config.h"
#include "sim/analysis/compare_manifest.h"
#include "sim/analysis/run_folder.h"

namespace ncosim::sim {

struct CompareOptions {
  std::string metric = "mse";  // a per-run column of runs.csv: mse, mse_ext, mde_percent, rmse_xI
  double tolerance = 0.0;      // relative: a change smaller than this is never a regression
  double alpha = 0.05;         // significance level of each one-sided test (family-wise with Holm)
  bool holm = true;            // Holm's correction over every tested row
  bool allow_scenario_change = false;  // compare folders of another scenario text, --set or inputs
};

struct CompareRow {
  std::vector<std::string> labels;
  std::string estimator;
  std::string verdict = "not comparable";  // better | unchanged | worse | not comparable
  std::string test = "none";               // paired | welch | none
  std::size_t runs_base = 0, runs_new = 0, pairs = 0;
  std::optional<double> base_mean, new_mean, diff, diff_low, diff_high;
  std::optional<double> relative, relative_low, relative_high;  // new / base - 1 and its CI
  std::optional<double> p_worse, p_better;                      // one-sided, Holm-adjusted if on
  std::string note;
};

struct CompareResult {
  CompareOptions options;
  RunFolder base,
      fresh;  // the two folders without their rows (dir, scenario, seed, sweep keys, ...)
  std::vector<CompareRow> rows;
  std::size_t tested = 0;  // rows with a test (the Holm family)
  std::size_t worse = 0, better = 0, unchanged = 0, not_comparable = 0;
  std::vector<std::string> warnings;
  std::vector<std::string> differences;  // every differing manifest field, "field: BASE -> NEW"
  int exit_code() const { return worse > 0 ? 1 : 0; }
};

CompareResult compare_folders(const RunFolder& base, const RunFolder& fresh,
                              const CompareOptions& options);

std::string compare_csv(const CompareResult& r);
std::string compare_markdown(const CompareResult& r);

// `ncosim compare BASE NEW [options]`: prints the Markdown table, writes compare.csv and
// compare.md into `out` (if not empty, atomically) and returns the exit code (0 or 1).
struct CompareCommand {
  std::string base, fresh, out;
  CompareOptions options;
  std::string correction = "holm";  // holm | none
};
int run_compare_command(const CompareCommand& c);

}  // namespace ncosim::sim
