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
#include "sim/analysis/summary_row.h"
#include "sim/files/csv.h"
#include "sim/files/output_set.h"
#include "sim/run/campaign.h"
#include "sim/scenario/scenario.h"

namespace ncosim::sim {

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

}  // namespace ncosim::sim
