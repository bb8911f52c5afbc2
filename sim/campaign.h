// sim/campaign.h — one Monte Carlo campaign: runs spread over threads, each a full
// event-driven simulation of the scenario with every estimator attached to the same
// realisation (common random numbers). Results are a pure function of (scenario, seed):
// identical for any thread count (per-run streams; aggregation in run order).
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "models/link_stats.h"
#include "sim/scenario.h"

namespace ncosim::sim {

// Metrics of one estimator in one run (sums over the periods k >= warmup).
struct EstimatorRunMetrics {
  double sse = 0.0;                 // sum |x - xhat|^2
  double sse_ext = 0.0;             // sum |xbar - xbar_hat|^2 (extended state)
  std::vector<double> sse_state;    // per plant state
  std::int64_t count = 0;           // periods counted
  std::int64_t samples_used = 0;    // samples the estimator used (in time, not duplicates)
  std::int64_t samples_taken = 0;   // samples taken by the sensors
  // Per sensor (the same in every estimator's record): samples taken and sent (k >= warmup),
  // and per sensor output the sum of the squared virtual noise m - y (held minus sampled;
  // 0 when sent) over the samples taken.
  std::vector<std::int64_t> sensor_taken, sensor_sent;
  std::vector<std::vector<double>> sensor_virtual_sse;
  bool diverged = false;            // a non-finite or > 1e150 error occurred
  std::string status = "ok";        // the estimator's own status at the end of the run
  // Mode estimators (scenarios with modes): periods k >= max(warmup, 1) scored, wrong estimates,
  // and the confusion counts [true * s + estimated] (s <= kMaxConfusionModes, else empty).
  std::int64_t mode_count = 0;
  std::int64_t mode_errors = 0;
  std::vector<std::int64_t> confusion;
  // FLOPs spent and packet bookkeeping, for estimators that count them (kalman_buffer).
  std::optional<est::Estimator::RunCounters> counters;
};

inline constexpr int kMaxConfusionModes = 64;

using RunMetrics = std::vector<EstimatorRunMetrics>;  // one per estimator

// Per-period record of run 0 (opt-in, for --trace).
struct TraceRow {
  std::int64_t period;
  std::vector<double> x;                    // true plant state
  std::vector<std::vector<double>> xhat;    // per estimator
  std::vector<int> arrivals;                // packets delivered this period, per sensor
  int mode = -1;                            // true mode of the transition into this period
  std::vector<int> mode_hat;                // per estimator (-1: none)
  std::vector<double> u;                    // input computed at this period (nu)
  std::vector<double> y;                    // true sensor outputs C x, stacked over the sensors
  double reference = 0.0;                   // controller reference (NaN when none)
};

struct CampaignOptions {
  int threads = 0;           // 0: all cores
  bool progress = false;     // progress line on stderr
  bool trace = false;        // record run 0 period by period
  bool time_estimators = true;  // measure ns_per_period by replaying run 0
  std::string progress_label;
};

struct CampaignResult {
  std::vector<RunMetrics> runs;          // [run][estimator]
  std::vector<double> ns_per_period;     // per estimator (measured), NaN when not measured
  std::vector<TraceRow> trace;           // run 0 when requested
  // [run][flow]: what each link did to each sender's packets (flows: sim/link_stats.h).
  std::vector<std::vector<models::LinkCounters>> link_runs;
  double wall_seconds = 0.0;
  int threads = 1;
};

// Simulates run `run` of the scenario. `trace` (optional) receives run 0's rows.
// `links` (optional) receives the run's link counters, one per flow (sim/link_stats.h).
RunMetrics simulate_run(const Scenario& sc, std::uint64_t run, std::vector<TraceRow>* trace = nullptr,
                        std::vector<double>* ns_per_period = nullptr,
                        std::vector<models::LinkCounters>* links = nullptr);

CampaignResult run_campaign(const Scenario& sc, const CampaignOptions& options);

}  // namespace ncosim::sim
