// sim/scenario/resource_limits.h — resource limits: every design and campaign is estimated (memory
// and work) before it starts and refused beyond the limits with a ScenarioError (exit 2) that names
// the key driving the size, the estimate and the limit. `--max-memory` / `--max-work` raise them.
// Out-of-memory that slips past the estimates is reported by the CLI as exit 1 with a message.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "config/config.h"
#include "estimators/estimator.h"
#include "lmi/limits.h"

namespace ncosim::sim {

struct ResourceLimits {
  double memory_bytes = 4e9;  // --max-memory MB (default 4000)
  double work_flops = 2e12;   // --max-work GFLOP (default 2000, about 5-20 minutes on one core)
};

// Process-wide limits (also handed to the LMI layer, lmi::set_resource_limits).
const ResourceLimits& resource_limits();
void set_resource_limits(const ResourceLimits& limits);

// "3.7 GB", "420 MB".
std::string human_bytes(double bytes);

// What sets the plant's state dimension, for messages: "plant.dead_time (1.01 s at run.period
// 0.005 s gives 204 states)" or "plant.A (300 states)".
// `raw` is the plant's TOML table (read without marking keys known).
std::string state_driver(const config::Table& plant, const toml::table& raw,
                         const est::Model& model);

// Before the design of estimator table `t` of kind `kind`: its kind's estimate `cost`
// (est::EstimatorRegistry::cost) against the limits. Throws ScenarioError naming what drives the
// size (cost.driver, else `driver`, the plant's state driver); prints a note for a large design.
void check_estimator_resources(const config::Table& t, const std::string& kind,
                               const est::DesignCost& cost, const std::string& driver);

// While estimator table `t` is designed: an observer of its LMI solves (lmi::ScopedSolveObserver)
// that prints, once, the note of a design estimated above 256 MB or 10 GFLOP (the LMI designs'
// estimate is only known when their problem is built).
std::function<void(const lmi::SolveEstimate&)> large_solve_note(const config::Table& t,
                                                                const std::string& kind,
                                                                const std::string& driver);

// Before a campaign: the per-run storage of runs x cases x estimators. Throws ScenarioError
// at run.runs.
void check_campaign_resources(const std::string& file, int line, std::int64_t runs,
                              std::size_t cases, std::size_t estimators, std::int64_t states,
                              std::size_t sensors);

// The error curves of one case or of every case of a sweep built so far ([run] error_curve):
// add() each case's shape (periods, estimators, states).
class CurveTotals {
 public:
  void add(std::int64_t periods, std::size_t estimators, std::int64_t states);
  // Peak memory (resource_limits.cc says how it was measured): an upper bound with a margin of
  // about 1.2 to 1.5 over the peak RSS measured.
  double bytes() const;
  std::size_t cases() const { return cases_; }
  double last_copy() const { return last_copy_; }  // one copy of the last case's curve
  std::string last_shape() const { return last_shape_; }

 private:
  std::size_t cases_ = 0;
  double largest_ = 0.0, exports_ = 0.0, last_copy_ = 0.0;
  std::string last_shape_;
};

// [run] error_curve = true: the curves of `totals` against --max-memory, and the last case's
// stored curve against SQLite's largest blob. Throws ScenarioError at FILE:LINE, key `key`.
void check_error_curve_resources(const std::string& file, int line, const std::string& key,
                                 const CurveTotals& totals);

// Before a trace link (kind = "trace") is used: every run counts the delivered packets per delay
// up to the trace's largest delay `delay` (links.csv's delay histogram, kept per run and in the
// run store), so memory grows with the delay times the runs. Throws ScenarioError at the
// trace's `line`, naming the delay, the estimate and the limit, then `named_by` (the scenario key).
void check_trace_resources(const std::string& trace, int line, std::int64_t delay,
                           std::int64_t runs, const std::string& named_by);

// Before a campaign on packet-level networks ([[network]]): ns-3's work, estimated as `seconds`
// of one core (`what` says what it counts), against --max-work (the design code's rate converts
// it). Throws ScenarioError at key `key` of `t`, the table whose size drives it.
void check_network_work(const config::Table& t, const std::string& key, double seconds,
                        const std::string& what);

// Before a campaign on packet-level networks: the memory their workers hold (`what` says how it
// is made up), `bytes` in all, against --max-memory. Throws ScenarioError at key `key` of `t`.
void check_network_memory(const config::Table& t, const std::string& key, double bytes,
                          const std::string& what);

// Before the cases of a sweep are built: every case holds its parsed document while it is built
// and its designed scenario until the campaign ends. Throws ScenarioError at the last sweep.
void check_sweep_resources(const std::string& file, int line, std::size_t cases,
                           std::size_t text_bytes);

}  // namespace ncosim::sim
