// sim/analysis/output.h — summaries and result files: summary.csv, summary.md, runs.csv,
// design.json, manifest.json, trajectory.csv. Every file is written to a temporary name and renamed
// only once all of them are complete, so a failure never leaves a half-written result set.
#pragma once

#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "sim/analysis/consistency.h"
#include "sim/analysis/paired.h"
#include "sim/run/campaign.h"
#include "sim/scenario/scenario.h"

namespace ncosim::sim {

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

// Half-width of the 95% confidence interval of the mean of `values` (Student t, n-1
// degrees of freedom); nullopt for fewer than 2 values.
std::optional<double> ci95_half_width(const std::vector<double>& values);

std::vector<SummaryRow> summarise(const Scenario& sc, const CampaignResult& result,
                                  const std::vector<std::string>& sweep_labels);

std::vector<std::string> summary_columns(const std::vector<SweepAxis>& sweeps, Eigen::Index n);
// confusion.csv: one row per (sweep case, mode estimator, true mode, estimated mode).
std::string confusion_csv(const std::vector<SweepAxis>& sweeps,
                          const std::vector<SummaryRow>& rows);

// summary.csv as text: the header and every row's cells, every column in file order.
struct SummaryText {
  std::vector<std::string> header;
  std::vector<std::vector<std::string>> cells;
};
SummaryText summary_text(const std::vector<SweepAxis>& sweeps, const std::vector<SummaryRow>& rows,
                         Eigen::Index n);
// The text of a SummaryText as CSV (RFC 4180 quoting): summary.csv, and `run --format csv`.
std::string summary_text_csv(const SummaryText& t);
// The columns of summary_text: summary_columns, then `stop` (with --target-ci),
// `expected_status` and the filter-consistency columns (nees .. consistency).
std::vector<std::string> summary_csv_columns(const std::vector<SweepAxis>& sweeps, Eigen::Index n,
                                             bool stop);
std::string summary_csv(const std::vector<SweepAxis>& sweeps, const std::vector<SummaryRow>& rows,
                        Eigen::Index n);
// The lines under the table for the rows whose filter is inconsistent (`consistency` neither
// empty nor "ok"): one per row with its NEES/NIS and bounds; empty when there is none.
std::string consistency_notes(const std::vector<SweepAxis>& sweeps,
                              const std::vector<SummaryRow>& rows);
std::string summary_markdown(const std::string& title, const std::vector<SweepAxis>& sweeps,
                             const std::vector<SummaryRow>& rows, Eigen::Index n);
std::string runs_csv(const std::vector<SweepAxis>& sweeps,
                     const std::vector<std::vector<std::string>>& labels,
                     const std::vector<const Scenario*>& scenarios,
                     const std::vector<const CampaignResult*>& results);
nlohmann::json design_json(const LoadedScenario& loaded);
// design.csv: one row per case and estimator (swept keys first), the design's predictions.
std::string design_csv(const LoadedScenario& loaded);
// Per case and sensor: samples taken and sent, the send ratio (beta) and per output the RMS of
// the virtual noise m - y (send-on-delta). Averaged over the runs.
std::string transmissions_csv(const std::vector<SweepAxis>& sweeps,
                              const std::vector<std::vector<std::string>>& labels,
                              const std::vector<const Scenario*>& scenarios,
                              const std::vector<const CampaignResult*>& results);
std::string trajectory_csv(const Scenario& sc, const std::vector<TraceRow>& trace);
// error_curve.csv ([run] error_curve): per case, estimator and period, the run-averaged squared
// error with its 95 % CI half-width and per state (sim/run/error_curve.h); curves[c] of case c.
std::string error_curve_csv(const std::vector<SweepAxis>& sweeps,
                            const std::vector<std::vector<std::string>>& labels,
                            const std::vector<const Scenario*>& scenarios,
                            const std::vector<ErrorCurve>& curves);

// Writes every (name, content) as the new result set of `dir`, atomically as a whole (a sibling
// folder fsynced and swapped in; see sim/files/output_set.h). Creates `dir` if needed. Throws
// std::runtime_error on failure (the previous set stays) and ScenarioError when another process
// holds the folder's lock. `stale` names earlier outputs to drop when they are not part of this
// set (e.g. a trajectory.csv of an earlier --trace run); every other existing entry is carried
// over, so the folder never mixes two result sets.
void write_files_atomically(const std::string& dir,
                            const std::vector<std::pair<std::string, std::string>>& files,
                            const std::vector<std::string>& stale = {});

// Creates `dir` and checks that its parent is writable (the set is swapped in from a sibling),
// before any work: throws std::runtime_error (ScenarioError for an empty folder name, the root or
// the current directory).
void prepare_output_dir(const std::string& dir);

// The status as the tables show it: `diverged (expected)` when the scenario expects it,
// `ok (expected diverged)` when it expected another; the bare status without expected_status.
std::string status_text(const SummaryRow& r);

// CSV field quoting (RFC 4180) and number formatting (empty for nullopt / non-finite).
std::string csv_field(const std::string& s);
std::string fmt_number(std::optional<double> v);

}  // namespace ncosim::sim
