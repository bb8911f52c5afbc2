// sim/analysis/summary_row.h — one row of summary.csv (an estimator in a case, over the runs), with
// the paired-comparison columns it carries (sim/analysis/paired.h fills them) and the texts that
// read one row or a list of rows: its status, and the notes on inconsistent filters.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "sim/analysis/consistency.h"
#include "sim/scenario/scenario_types.h"

namespace ncosim::sim {

// Per metric: the paired difference and ratio of a row against its reference, 95 % CI.
struct PairedMetric {
  std::optional<double> diff, diff_ci95, ratio, ratio_ci95;
};
struct PairedColumns {
  std::string reference;           // the reference estimator (within the case)
  PairedMetric mse, mse_ext, mde;  // against the reference estimator, same case and runs
  std::string reference_case;      // "KEY=VALUE; ..." (sweeps only)
  PairedMetric case_mse, case_mse_ext,
      case_mde;  // against the same estimator in the reference case
};

// The per-run values summarise() uses (empty when any run diverged, as the summary columns).
struct PerRunValues {
  std::vector<double> mse, mse_ext, mde;  // in the order of `run`
  std::vector<std::uint64_t> run;         // the run index of each value (runs are paired by it)
  std::uint64_t seed = 0;
};

// One row of summary.csv.
struct SummaryRow {
  std::vector<std::string> sweep_labels;
  std::string estimator, kind;
  std::int64_t runs = 0;
  std::optional<double> mse, mse_ci95, mse_ext, mse_ext_ci95;
  std::vector<std::optional<double>> rmse;  // per plant state
  std::optional<double> mde_percent;
  std::optional<double> flops_per_period;
  std::optional<long> stored_gains;
  std::optional<double> ns_per_period;
  std::optional<double> predicted_mse_ext;
  std::optional<double> delivered_ratio;
  std::string status;
  // After status (columns added later keep the earlier positions):
  std::optional<double> mde_ci95;
  std::vector<std::optional<double>> ermse, ermse_ci95;  // per plant state: mean of per-run roots
  std::optional<double> mde_run_min, mde_run_max;        // spread of the per-run MDE
  std::vector<std::int64_t> confusion;                   // s x s, summed over runs
  int modes = 0;
  // After status (appended columns):
  std::optional<double> predicted_mse;  // the design's analytic mean |x - xhat|^2, where one exists
  std::optional<double> flops_mean;     // FLOPs per period averaged over every run (kalman_buffer)
  std::optional<double> sent_per_period;  // packets sent by all sensors per period (k >= warmup)
  // With --target-ci only (the column exists only then): why the campaign stopped.
  std::string stop;
  // After the ermse columns: paired differences against the reference (sim/analysis/paired.h).
  PairedColumns paired;
  PerRunValues per_run;     // the per-run values the paired columns use (not written)
  std::string model_check;  // the prediction against the simulation (sim/analysis/validity.h)
  // After model_check (and stop): [[estimator]] expected_status, "" when not declared ("ok").
  std::string expected_status;
  // After expected_status: filter consistency (sim/analysis/consistency.h), for estimators with a
  // covariance (NEES) or innovations (NIS); `consistency` is "ok" or what is out of bounds.
  std::optional<ConsistencyStat> nees, nis;
  std::string consistency;
};

// The status as the tables show it: `diverged (expected)` when the scenario expects it,
// `ok (expected diverged)` when it expected another; the bare status without expected_status.
std::string status_text(const SummaryRow& r);
// The lines under the table for the rows whose filter is inconsistent (`consistency` neither
// empty nor "ok"): one per row with its NEES/NIS and bounds; empty when there is none.
std::string consistency_notes(const std::vector<SweepAxis>& sweeps,
                              const std::vector<SummaryRow>& rows);

}  // namespace ncosim::sim
