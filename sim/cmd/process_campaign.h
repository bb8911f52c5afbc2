// sim/cmd/process_campaign.h — a campaign over worker processes, for scenarios whose runs cannot
// share a process: ns-3 (the [[network]] tables, network/) has one simulator per process, so the
// runs of such a scenario would otherwise take turns on one core. The ncosim process forks one
// single-threaded worker per --threads before anything simulates; it hands out one run at a time
// over a pipe (a dynamic queue, so unequal runs balance) and receives each run's serialized
// metrics, link counters and, at the end, the worker's error curve. Results are bit-identical to
// one process (a run depends on (seed, run index) alone, and the store orders every export).
#pragma once

#include <functional>
#include <string>

#include "sim/run/campaign.h"

namespace ncosim::sim {

// Whether the scenario's runs need worker processes to use more than one core (it has networks).
bool needs_worker_processes(const Scenario& sc);

// The runs of `options.only_runs` over min(options.threads or every core, runs) worker processes;
// each result goes to options.on_run in the calling process. The trace of run 0 and the
// estimators' timing (when asked) come from one more simulation of the first run here, after the
// distribution. A run whose process dies (a crash inside ns-3: NS_FATAL_ERROR, NS_ASSERT, a
// signal) is reported once on stderr (report_run_failure) and delivered as failed_run_metrics; the
// other runs go on. A worker process that dies, or a run that throws, ends the campaign with a
// message naming the run.
CampaignResult run_in_processes(const Scenario& sc, const CampaignOptions& options);

// One run simulated in a process of its own, forked from this one (ns-3 keeps state across the
// simulations of one process, so every run of a network scenario starts from the same state).
struct ChildRun {
  RunMetrics metrics;
  RunLinks links;       // empty unless asked
  ErrorCurve curve;     // this run's errors with [run] error_curve, else empty
  std::string error;    // the run threw (an ncosim error): the campaign should stop
  std::string failure;  // the process died: why, with the last line it wrote on stderr
};
// Whatever the child writes on stderr is held and, when it ends normally, written on this
// process's stderr; when it dies, its last line goes into `failure`. The child never returns into
// the caller's code (it ends with _exit), so an MPI rank may call this too.
ChildRun run_in_child(const Scenario& sc, std::uint64_t run, bool link_counters);

// The status of every estimator's record of a run whose process died.
inline constexpr const char* kNetworkFailure = "network_failure";
// The record of such a run: per estimator, status kNetworkFailure, counted as diverged (no errors,
// excluded from every error statistic; results/README.md, `status`).
RunMetrics failed_run_metrics(const Scenario& sc);
// "ncosim: run RUN: network_failure: FAILURE" on stderr.
void report_run_failure(std::uint64_t run, const std::string& failure);

// Run `run`'s trace, simulated in a process of its own (so that this process never simulates a
// network, and the workers it forks later start from the same state).
std::vector<TraceRow> trace_in_child(const Scenario& sc, std::uint64_t run);
// The estimators' timing (simulate_run's ns_per_period) on run `run`, simulated in a process of
// its own likewise.
std::vector<double> timing_in_child(const Scenario& sc, std::uint64_t run);

// Runs `work` in a forked process of its own (ns-3 keeps state across the simulations of one
// process) and returns the bytes it returned. Throws, naming `what`, when the process ends
// without them (a crash inside ns-3, or `work` threw).
std::string bytes_from_child(const std::function<std::string()>& work, const std::string& what);

}  // namespace ncosim::sim
