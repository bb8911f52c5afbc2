// sim/run/campaign.cc — the campaign: runs (sim/run/run.h) distributed over threads, counting
// progress (sim/run/progress.h), with stop.
#include "sim/run/campaign.h"

#include <fmt/format.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <exception>
#include <iostream>
#include <mutex>
#include <system_error>
#include <thread>

#include "kernel/check.h"
#include "sim/run/progress.h"
#include "sim/run/run.h"

namespace ncosim::sim {

namespace {

// `count` threads running `worker`. When one cannot be created: `stop` (no new run), join those
// started, and fail with a message (never the abort of a joinable std::thread destroyed).
template <class Worker, class Stop>
std::vector<std::thread> start_workers(int count, Worker& worker, Stop stop) {
  std::vector<std::thread> pool;
  try {
    for (int t = 0; t < count; ++t) pool.emplace_back(worker);
  } catch (const std::system_error& e) {
    stop();
    for (auto& t : pool) t.join();
    throw std::runtime_error(
        fmt::format("cannot start worker thread {} of {} ({}); retry with a smaller --threads",
                    pool.size() + 2, count + 1, e.what()));
  }
  return pool;
}

// A stopped campaign keeps the completed runs only, with their run indices.
void keep_completed(const std::vector<std::uint64_t>& todo, const std::vector<char>& completed,
                    bool link_counters, CampaignResult& result) {
  std::vector<RunMetrics> kept;
  std::vector<RunLinks> kept_links;
  std::vector<std::uint64_t> ids;
  for (std::size_t i = 0; i < todo.size(); ++i) {
    if (completed[i] != 0) {
      kept.push_back(std::move(result.runs[i]));
      if (link_counters) kept_links.push_back(std::move(result.link_runs[i]));
      ids.push_back(todo[i]);
    }
  }
  result.runs = std::move(kept);
  result.link_runs = std::move(kept_links);
  result.run_ids = std::move(ids);
}

}  // namespace

ErrorCurve error_curve_of(const Scenario& sc) {
  return ErrorCurve(sc.run.periods, sc.estimators.size(), sc.model.plant.n());
}

RunMetrics failed_run_metrics(const Scenario& sc) {
  RunMetrics m(sc.estimators.size());
  for (EstimatorRunMetrics& e : m) {
    e.diverged = true;
    e.status = kNetworkFailure;
    // Every per-state and per-sensor vector sized, with nothing counted: the exports index them.
    e.sse_state.assign(static_cast<std::size_t>(sc.model.plant.n()), 0.0);
    e.sensor_taken.assign(sc.model.sensors.size(), 0);
    e.sensor_sent.assign(sc.model.sensors.size(), 0);
    for (const auto& s : sc.model.sensors)
      e.sensor_virtual_sse.emplace_back(static_cast<std::size_t>(s.spec.ny()), 0.0);
  }
  return m;
}

void report_run_failure(std::uint64_t run, const std::string& failure) {
  std::cerr << fmt::format("ncosim: run {}: {}: {}; the campaign goes on without its results\n",
                           run, kNetworkFailure, failure)
            << std::flush;
}

RunMetrics campaign_run(const Scenario& sc, std::uint64_t run, RunLinks* links, ErrorCurve* curve,
                        std::string& failure, std::vector<TraceRow>* trace, ReplayLog* log) {
  if (!sc.networks.needs_own_process()) {
    RunMetrics m = execute_run(sc, run, trace, log, links, curve);
    if (curve != nullptr) curve->add_run(run);
    return m;
  }
  // A run whose network may die: its errors are added to the curve only once it has ended.
  ErrorCurve own = curve != nullptr ? error_curve_of(sc) : ErrorCurve();
  try {
    RunMetrics m = execute_run(sc, run, trace, log, links, curve != nullptr ? &own : nullptr);
    if (curve != nullptr) {
      own.add_run(run);
      curve->merge(std::move(own));
    }
    return m;
  } catch (const network::EngineFailure& e) {
    failure = e.what();
    if (links != nullptr) links->clear();
    if (trace != nullptr) trace->clear();
    if (log != nullptr) {
      const std::size_t limit = log->limit;
      *log = ReplayLog();
      log->limit = limit;
    }
    return failed_run_metrics(sc);
  }
}

RunMetrics simulate_run(const Scenario& sc, std::uint64_t run, std::vector<TraceRow>* trace,
                        std::vector<double>* ns_per_period,
                        std::vector<models::LinkCounters>* links, ErrorCurve* curve) {
  ReplayLog log;
  RunMetrics m =
      execute_run(sc, run, trace, ns_per_period != nullptr ? &log : nullptr, links, curve);
  if (curve != nullptr) curve->add_run(run);
  if (ns_per_period != nullptr)
    *ns_per_period = time_estimators(sc, log, std::chrono::milliseconds(200));
  return m;
}

namespace {

// The run indices a campaign simulates: options.only_runs, else 0 .. runs-1.
std::vector<std::uint64_t> runs_to_do(const Scenario& sc, const CampaignOptions& options) {
  if (options.only_runs) return *options.only_runs;
  std::vector<std::uint64_t> todo(static_cast<std::size_t>(sc.run.runs));
  for (std::size_t r = 0; r < todo.size(); ++r) todo[r] = r;
  return todo;
}

// Worker threads: options.threads (0: every core), at most one per run, one with libsumo.
int campaign_threads(const Scenario& sc, const CampaignOptions& options, std::size_t runs) {
  int threads =
      options.threads > 0 ? options.threads : static_cast<int>(std::thread::hardware_concurrency());
  threads = std::max(1, std::min<int>(threads, static_cast<int>(std::max<std::size_t>(runs, 1))));
  if (sc.mobility && sc.mobility->single_threaded()) threads = 1;  // one libsumo per process
  return threads;
}

// ns_per_period: timed alone, after the campaign, on a replay of the first run simulated (at
// most kReplayPeriods periods; not part of the results' identity). Budget per estimator: 2 % of
// the campaign's time, between 1 ms and 200 ms. NaN when not timed.
std::vector<double> time_campaign(const Scenario& sc, const ReplayLog& log, bool timed,
                                  double wall_seconds) {
  if (!timed) return std::vector<double>(sc.estimators.size(), std::nan(""));
  const double share =
      0.02 * wall_seconds / static_cast<double>(std::max<std::size_t>(sc.estimators.size(), 1));
  const auto budget =
      std::chrono::nanoseconds(static_cast<std::int64_t>(std::clamp(share, 0.001, 0.2) * 1e9));
  return time_estimators(sc, log, budget);
}

// The log of the first run simulated here, for the timing: at most kReplayPeriods periods and at
// most 2 % of the periods this call simulates (at least 200), so that one replay of every
// estimator costs about 2 % of the campaign.
ReplayLog timing_log(const Scenario& sc, std::size_t runs) {
  ReplayLog log;
  log.limit = std::min<std::size_t>(
      kReplayPeriods,
      std::max<std::size_t>(200, static_cast<std::size_t>(sc.run.periods) * runs / 50));
  return log;
}

}  // namespace

CampaignResult run_campaign(const Scenario& sc, const CampaignOptions& options) {
  CampaignResult result;
  const std::vector<std::uint64_t> todo = runs_to_do(sc, options);
  const std::size_t runs = todo.size();
  const bool keep = !options.on_run;
  if (keep) {
    result.runs.resize(runs);
    if (options.link_counters) result.link_runs.resize(runs);
    if (options.only_runs) result.run_ids = todo;
  }
  const int threads = campaign_threads(sc, options, runs);
  result.threads = threads;
  const auto start = std::chrono::steady_clock::now();

  ReplayLog log = timing_log(sc, runs);
  std::atomic<std::size_t> next{0}, done{0};
  std::exception_ptr error;
  std::mutex error_mutex, sink_mutex;
  std::atomic<bool> failed{false};
  std::vector<char> completed(keep ? runs : 0, 0);
  // [run] error_curve: one curve per thread (allocated by the thread), summed after the join.
  std::vector<ErrorCurve> curves(static_cast<std::size_t>(threads));
  std::atomic<std::size_t> slots{0};
  auto stop_requested = [&] { return options.stop != nullptr && options.stop->load() != 0; };
  auto worker = [&] {
    ErrorCurve* curve = nullptr;
    if (sc.run.error_curve) {
      curve = &curves[slots.fetch_add(1)];
      *curve = error_curve_of(sc);
    }
    while (true) {
      if (stop_requested()) return;
      const std::size_t i = next.fetch_add(1);
      if (i >= runs) return;
      const std::uint64_t r = todo[i];
      try {
        ReplayLog* lg = i == 0 && options.time_estimators ? &log : nullptr;
        RunLinks links;
        std::string failure;
        RunMetrics m = campaign_run(sc, r, options.link_counters ? &links : nullptr, curve, failure,
                                    r == 0 && options.trace ? &result.trace : nullptr, lg);
        if (!failure.empty()) report_run_failure(r, failure);
        if (keep) {
          result.runs[i] = std::move(m);
          if (options.link_counters) result.link_runs[i] = std::move(links);
          completed[i] = 1;
        } else {
          std::lock_guard<std::mutex> lock(sink_mutex);
          options.on_run(r, std::move(m), std::move(links));
        }
      } catch (...) {
        std::lock_guard<std::mutex> lock(error_mutex);
        if (!error) error = std::current_exception();
        failed = true;
        next = runs;
        return;
      }
      done.fetch_add(1);
      if (options.progress != nullptr) options.progress->add_done();
    }
  };
  std::vector<std::thread> pool = start_workers(threads - 1, worker, [&] { next = runs; });
  worker();
  for (auto& t : pool) t.join();
  if (error) std::rethrow_exception(error);
  for (ErrorCurve& c : curves) result.curve.merge(std::move(c));
  result.runs_done = done.load();
  result.stopped = result.runs_done < runs;
  if (keep && result.stopped) keep_completed(todo, completed, options.link_counters, result);
  result.wall_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  result.ns_per_period = time_campaign(
      sc, log, options.time_estimators && !log.u.empty() && !stop_requested(), result.wall_seconds);
  return result;
}

}  // namespace ncosim::sim
