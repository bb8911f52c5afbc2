// sim/run/campaign.h — one Monte Carlo campaign: runs spread over threads, each a full
// event-driven simulation of the scenario with every estimator attached to the same
// realisation (common random numbers). Results are a pure function of (scenario, seed):
// identical for any thread count (per-run streams; aggregation in run order).
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "sim/run/error_curve.h"
#include "sim/run/run.h"
#include "sim/run/run_results.h"
#include "sim/scenario/scenario.h"

namespace ncosim::sim {

class CampaignProgress;  // sim/run/progress.h

struct CampaignOptions {
  int threads = 0;  // 0: all cores
  // The campaign-wide progress line (sim/run/progress.h), owned by the caller: each completed run
  // is counted there (null: none).
  CampaignProgress* progress = nullptr;
  bool trace = false;           // record run 0 period by period
  bool time_estimators = true;  // measure ns_per_period by replaying the first run simulated
  // The run indices to simulate, ascending (nullopt: 0 .. runs-1). Resume and shards.
  std::optional<std::vector<std::uint64_t>> only_runs;
  // Count what every link does to every sender's packets (CampaignResult::link_runs, or the
  // `links` of on_run; empty when off). Never changes a draw: off only to measure its cost.
  bool link_counters = true;
  // Receives each completed run with its link counters (called from the worker threads, one at
  // a time); when set, CampaignResult::runs stays empty, so a campaign's memory does not grow
  // with its runs.
  std::function<void(std::uint64_t run, RunMetrics&& metrics, RunLinks&& links)> on_run;
  // Set (e.g. by a signal handler): no new run is started; runs in progress finish.
  const std::atomic<int>* stop = nullptr;
};

// Simulates run `run` of the scenario. `trace` (optional) receives run 0's rows.
// `links` (optional) receives the run's link counters, one per flow (sim/run/link_report.h).
// `curve` (optional, of the scenario's shape: error_curve_of) receives the run's errors.
RunMetrics simulate_run(const Scenario& sc, std::uint64_t run,
                        std::vector<TraceRow>* trace = nullptr,
                        std::vector<double>* ns_per_period = nullptr, RunLinks* links = nullptr,
                        ErrorCurve* curve = nullptr);
// An empty error curve of the scenario's shape (periods x estimators x plant states).
ErrorCurve error_curve_of(const Scenario& sc);

// One run as a campaign runs it: simulate_run's outputs (the links, the errors added to `curve`
// with add_run, run 0's trace, the replay log). A run whose network died
// (network::EngineFailure: its worker process ended abnormally, e.g. ns-3 aborted) is no error:
// `failure` says why, and the run is failed_run_metrics, with no links and nothing added to the
// curve, the trace or the log.
RunMetrics campaign_run(const Scenario& sc, std::uint64_t run, RunLinks* links, ErrorCurve* curve,
                        std::string& failure, std::vector<TraceRow>* trace = nullptr,
                        ReplayLog* log = nullptr);

// The status of every estimator's record of a run whose network died.
inline constexpr const char* kNetworkFailure = "network_failure";
// The record of such a run: per estimator, status kNetworkFailure, counted as diverged (no errors,
// excluded from every error statistic; results/README.md, `status`).
RunMetrics failed_run_metrics(const Scenario& sc);
// "ncosim: run RUN: network_failure: FAILURE; the campaign goes on without its results" on stderr.
void report_run_failure(std::uint64_t run, const std::string& failure);

CampaignResult run_campaign(const Scenario& sc, const CampaignOptions& options);

}  // namespace ncosim::sim
