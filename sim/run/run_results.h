// sim/run/run_results.h — what runs produce: one estimator's metrics in one run, the link
// counters and the trace of a run, and a campaign's results (sim/run/campaign.h runs them).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "estimators/estimator.h"
#include "models/link_stats.h"
#include "sim/run/error_curve.h"

namespace ncosim::sim {

// Metrics of one estimator in one run (sums over the periods k >= warmup).
struct EstimatorRunMetrics {
  double sse = 0.0;                // sum |x - xhat|^2
  double sse_ext = 0.0;            // sum |xbar - xbar_hat|^2 (extended state)
  std::vector<double> sse_state;   // per plant state
  std::int64_t count = 0;          // periods counted
  std::int64_t samples_used = 0;   // samples the estimator used (in time, not duplicates)
  std::int64_t samples_taken = 0;  // samples taken by the sensors
  // Per sensor (the same in every estimator's record): samples taken and sent (k >= warmup),
  // and per sensor output the sum of the squared virtual noise m - y (held minus sampled;
  // 0 when sent) over the samples taken.
  std::vector<std::int64_t> sensor_taken, sensor_sent;
  std::vector<std::vector<double>> sensor_virtual_sse;
  bool diverged = false;      // a non-finite or > 1e150 error occurred
  std::string status = "ok";  // the estimator's own status at the end of the run
  // Mode estimators (scenarios with modes): periods k >= max(warmup, 1) scored, wrong estimates,
  // and the confusion counts [true * s + estimated] (s <= kMaxConfusionModes, else empty).
  std::int64_t mode_count = 0;
  std::int64_t mode_errors = 0;
  std::vector<std::int64_t> confusion;
  // FLOPs spent and packet bookkeeping, for estimators that count them (kalman_buffer).
  std::optional<est::Estimator::RunCounters> counters;
  // Filter consistency over k >= warmup (results/README.md, "nees and nis"): for estimators with
  // a covariance, the sum of e' P^-1 e (e = x - xhat, P the state block of covariance()) over the
  // periods where P is positive definite, and their count; for estimators with innovations
  // (est::Estimator::innovations), the sums over the updates of those periods.
  double nees = 0.0;
  std::int64_t nees_count = 0;
  double nis = 0.0;
  std::int64_t nis_dof = 0, nis_count = 0;
  // The counted periods k >= warmup cut in kErrorBlocks blocks of L = floor(#K / kErrorBlocks)
  // periods (the last #K - kErrorBlocks L periods in none): per block, sum |x - xhat|^2. Empty when
  // #K < kErrorBlocks; what the error-growth note fits a trend to (sim/run/overload.h).
  std::vector<double> sse_blocks;
};

inline constexpr int kMaxConfusionModes = 64;
inline constexpr std::int64_t kErrorBlocks = 16;

using RunMetrics = std::vector<EstimatorRunMetrics>;  // one per estimator
// What each link did to each sender's packets in one run, one entry per flow
// (sim/run/link_report.h).
using RunLinks = std::vector<models::LinkCounters>;

// Per-period record of run 0 (opt-in, for --trace).
struct TraceRow {
  std::int64_t period;
  std::vector<double> x;                  // true plant state
  std::vector<std::vector<double>> xhat;  // per estimator
  std::vector<int> arrivals;              // packets delivered this period, per sensor
  int mode = -1;                          // true mode of the transition into this period
  std::vector<int> mode_hat;              // per estimator (-1: none)
  std::vector<double> u;                  // input computed at this period (nu)
  std::vector<double> y;                  // true sensor outputs C x, stacked over the sensors
  double reference = 0.0;                 // controller reference (NaN when none)
};

// One packet a sensor sent over a network link, and its fate: its delay (periods from the sample
// to its arrival) or models::kLost.
struct RecordedPacket {
  std::int64_t period = 0;
  std::size_t sensor = 0;
  std::int64_t delay = 0;
};

struct CampaignResult {
  std::vector<RunMetrics> runs;        // [run][estimator]
  std::vector<std::uint64_t> run_ids;  // the run index of each entry of `runs` (empty: 0, 1, ...)
  std::size_t runs_done = 0;           // runs completed by this call
  bool stopped = false;                // `stop` was set before every run was done
  std::vector<double> ns_per_period;   // per estimator (measured), NaN when not measured
  std::vector<TraceRow> trace;         // run 0 when requested
  // [run][flow], aligned with `runs` (empty when CampaignOptions::link_counters is off).
  std::vector<RunLinks> link_runs;
  double wall_seconds = 0.0;
  int threads = 1;
  // [run] error_curve: the runs completed by this call, summed (sim/run/error_curve.h); else empty.
  ErrorCurve curve;
};

}  // namespace ncosim::sim
