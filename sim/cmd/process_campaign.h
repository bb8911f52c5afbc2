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
// distribution. A worker that dies (a crash inside ns-3) or fails ends the campaign with a message
// naming the run.
CampaignResult run_in_processes(const Scenario& sc, const CampaignOptions& options);

// Run `run`'s trace, simulated in a process of its own (so that this process never simulates a
// network, and the workers it forks later start from the same state).
std::vector<TraceRow> trace_in_child(const Scenario& sc, std::uint64_t run);

// Runs `work` in a forked process of its own (ns-3 keeps state across the simulations of one
// process) and returns the bytes it returned. Throws, naming `what`, when the process ends
// without them (a crash inside ns-3, or `work` threw).
std::string bytes_from_child(const std::function<std::string()>& work, const std::string& what);

}  // namespace ncosim::sim
