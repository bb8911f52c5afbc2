// sim/analysis/compare.h — `ncosim compare BASE NEW`: two output folders of the same scenario
// compared row by row (sweep case, estimator) on one per-run metric of runs.csv, as a CI gate
// (docs/compare.md). Runs are matched by (seed, run index): where both folders ran the same seed
// the row is paired on the runs they share (common random numbers), otherwise unpaired. Each row
// is judged on the per-run ratio NEW / BASE (its logarithm): the Wilcoxon signed-rank test
// (paired) or rank-sum test (unpaired) with the Hodges–Lehmann estimate of the typical ratio and
// the interval that inverts the test (sim/analysis/rank_tests.h): exact whatever the tails of the
// per-run values. Verdicts against the relative --tolerance T: "worse" when the typical ratio is
// significantly above 1 + T, "better" significantly below 1 - T, "unchanged" when the (1 - 2
// alpha) interval lies inside (1 - T, 1 + T) (an equivalence test, TOST), "inconclusive"
// otherwise; each family of claims Holm-corrected over the tested rows, each printed interval at
// the level that decided its row (so that it reads as its verdict). "not comparable" when no test
// applies. Folders of the same scenario text and --set (scenario_text_hash) compare whatever their
// --runs, --periods or --seed; another text or other inputs need --allow-scenario-change. Every
// manifest field that differs is named, one line each (sim/analysis/compare_manifest.h).
// Bad input (unreadable or malformed files, a metric cell that is not a finite number >= 0,
// different scenarios, missing rows, a bad option) throws CompareInputError naming the FILE (and
// LINE) or the option (exit 2). runs.csv is streamed: memory follows the runs of the metric.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "config/config.h"
#include "sim/analysis/compare_manifest.h"
#include "sim/analysis/compare_stats.h"
#include "sim/analysis/run_folder.h"

namespace ncosim::sim {

struct CompareResult {
  CompareOptions options;
  RunFolder base,
      fresh;  // the two folders without their rows (dir, scenario, seed, sweep keys, ...)
  std::vector<CompareRow> rows;
  std::size_t tested = 0;  // rows with a test (the Holm family)
  std::size_t worse = 0, better = 0, unchanged = 0, inconclusive = 0, not_comparable = 0;
  std::vector<std::string> warnings;
  std::vector<std::string> differences;  // every differing manifest field, "field: BASE -> NEW"
  // 1 (kCompareWorse) with a worse row, else 4 (kCompareInconclusive) with an inconclusive row
  // unless options.allow_inconclusive, else 0.
  int exit_code() const;
};

CompareResult compare_folders(const RunFolder& base, const RunFolder& fresh,
                              const CompareOptions& options);

std::string compare_csv(const CompareResult& r);
std::string compare_markdown(const CompareResult& r);

// `ncosim compare BASE NEW [options]`: prints the Markdown table, writes compare.csv and
// compare.md into `out` (if not empty, atomically) and returns the exit code (0, 1 or 4). Checks
// the options first (CompareInputError naming the option: nothing read or written).
struct CompareCommand {
  std::string base, fresh, out;
  CompareOptions options;
  std::string correction = "holm";  // holm | none
};
int run_compare_command(const CompareCommand& c);
// The options' ranges (CompareInputError naming the option): alpha in (0, 0.5), tolerance in
// [0, 1), and 0 only with allow_inconclusive.
void check_compare_options(const CompareOptions& o);

}  // namespace ncosim::sim
