// sim/cmd/batch.cc — campaigns on the command line (see batch.h).
#include "sim/cmd/batch.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <charconv>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <thread>

#include "ncosim_version.h"
#include "sim/analysis/output.h"
#include "sim/analysis/paired.h"
#include "sim/cmd/manifest.h"
#include "sim/cmd/mpi_campaign.h"
#include "sim/cmd/store_sink.h"
#include "sim/files/output_set.h"
#include "sim/present/table_view.h"
#include "sim/run/campaign.h"
#include "sim/run/link_report.h"
#include "sim/run/progress.h"
#include "sim/scenario/resource_limits.h"
#include "sim/store/store.h"

namespace ncosim::sim {

namespace {

// --target-ci, --max-runs and --replace checked before the scenario is read.
void check_target_options(const RunCommand& cmd) {
  if (cmd.replace && cmd.resume) {
    throw config::ScenarioError(
        "--replace: not with --resume (--resume continues the stored campaign, --replace discards "
        "it)");
  }
  if (!cmd.target_ci && cmd.max_runs > 0)
    throw config::ScenarioError("--max-runs: only with --target-ci");
  if (cmd.target_ci &&
      (!std::isfinite(*cmd.target_ci) || *cmd.target_ci <= 0.0 || *cmd.target_ci >= 1.0)) {
    throw config::ScenarioError(
        fmt::format("--target-ci: expected a relative half-width in (0, 1), e.g. 0.01, got {}",
                    *cmd.target_ci));
  }
  if (cmd.target_ci && cmd.max_runs <= 0) {
    throw config::ScenarioError(
        "--target-ci: --max-runs N is required (the most runs per case before giving up)");
  }
}

// The --target-ci rule of the campaign (off without the option), checked against its cases and
// recorded in `meta`.
TargetRule target_rule(const RunCommand& cmd, const LoadedScenario& loaded,
                       std::map<std::string, std::string>& meta) {
  if (!cmd.target_ci) return TargetRule{};
  const auto batch = loaded.cases.front().scenario->run.runs;
  for (const auto& c : loaded.cases) {
    if (c.scenario->run.runs != batch) {
      throw config::ScenarioError(
          "--target-ci: every sweep case must have the same run.runs (the batch size)");
    }
  }
  if (cmd.max_runs < batch) {
    throw config::ScenarioError(fmt::format(
        "--max-runs: expected at least run.runs = {} (one batch), got {}", batch, cmd.max_runs));
  }
  bool reachable = false;
  for (const auto& c : loaded.cases) {
    for (const auto& e : c.scenario->estimators)
      reachable = reachable || e.design->report().status == "ok";
  }
  if (!reachable)
    throw config::ScenarioError(
        "--target-ci: no estimator has a working design, so no row has an mse to reach the target");
  meta["target_ci"] = fmt::format("{:.17g}", *cmd.target_ci);
  meta["max_runs"] = std::to_string(cmd.max_runs);
  return target_of(meta, loaded);
}

// What a new campaign would replace in the folder: a store holding finished runs of a different
// campaign, or of this one unfinished.
struct ReplacedStore {
  std::string path;
  std::int64_t runs = 0;
  std::string diff;         // what differs (stored vs now); "" for the same campaign
  bool unfinished = false;  // the store beside the folder, or the folder's without every run
};

// Whether the folder's store of this very campaign holds every run it owns (with --target-ci:
// it was not stopped before the target or --max-runs decided).
bool store_finished(const RunStore& store, const LoadedScenario& loaded,
                    const std::map<std::string, std::string>& meta) {
  if (target_of(meta, loaded).on()) return meta.count("stopped") == 0 || meta.at("stopped").empty();
  const Shard shard = shard_of(meta);
  for (std::size_t c = 0; c < loaded.cases.size(); ++c) {
    if (store.done_runs(c).size() < owned_runs(*loaded.cases[c].scenario, shard)) return false;
  }
  return true;
}

// The store at `path` if replacing it would lose runs (`partial`: the unfinished store beside
// the folder); nothing for no store, no run, the same finished campaign or an unreadable store.
std::optional<ReplacedStore> replaced_store(const std::string& path, bool partial,
                                            const LoadedScenario& loaded,
                                            const std::map<std::string, std::string>& meta) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) return std::nullopt;
  ReplacedStore r{path, 0, "", partial};
  try {
    const RunStore store = RunStore::open(path, false);
    r.runs = store.count_runs();
    if (r.runs == 0) return std::nullopt;
    const auto stored = store.meta();
    check_campaign_meta(stored, path);
    r.diff = identity_difference(stored, meta, true);
    if (!partial && r.diff.empty()) r.unfinished = !store_finished(store, loaded, stored);
  } catch (const StoreError&) {
    return std::nullopt;  // damaged: nothing in it can be resumed or exported (as before: replaced)
  }
  if (r.diff.empty() && !r.unfinished)
    return std::nullopt;  // the same campaign again: identical results
  return r;
}

// Without --resume: refuses (exit 2, nothing written) to replace a store of the folder that holds
// finished runs of a different or unfinished campaign, unless --replace says so (then says what
// it replaces; true).
bool check_replace(const RunCommand& cmd, const LoadedScenario& loaded,
                   const std::map<std::string, std::string>& meta) {
  std::optional<ReplacedStore> r = replaced_store(partial_store_path(cmd.out), true, loaded, meta);
  if (!r) r = replaced_store(store_path(cmd.out), false, loaded, meta);
  if (!r) return false;
  if (cmd.replace) {
    std::cerr << fmt::format(
        "ncosim: --replace: replacing {} finished run(s) of {} campaign in {}\n", r->runs,
        r->diff.empty() ? "an unfinished" : "a different", r->path);
    return true;
  }
  const std::string what = r->diff.empty() ? "an unfinished campaign"
                           : r->unfinished ? "a different, unfinished campaign"
                                           : "a different campaign";
  throw config::ScenarioError(
      fmt::format("--out: '{}' holds {} finished run(s) of {} ({}){}; {}`--replace` starts afresh "
                  "and replaces them, or choose "
                  "another --out",
                  cmd.out, r->runs, what, r->path,
                  r->diff.empty() ? "" : fmt::format(": {} differ(s) (stored vs now)", r->diff),
                  r->diff.empty() ? "`--resume` continues it, " : ""));
}

// The run store of the campaign, always built beside the folder (partial_store_path): created
// afresh, or with --resume the stored campaign, which must be this one: the unfinished one beside
// the folder if a session was killed, else a copy of the set's store. The folder's set is not
// touched until the new one is swapped in.
RunStore open_run_store(const RunCommand& cmd, const LoadedScenario& loaded,
                        const std::map<std::string, std::string>& meta) {
  namespace fs = std::filesystem;
  const std::string partial = partial_store_path(cmd.out), live = store_path(cmd.out);
  settle_partial(cmd.out);
  std::error_code ec;
  if (!cmd.resume) {
    if (!check_replace(cmd, loaded, meta)) note_replaced_partial(cmd.out, partial);
    return RunStore::create(partial, meta);
  }
  auto same_campaign = [&](const RunStore& s, const std::string& what) {
    const auto stored = s.meta();
    check_campaign_meta(stored, what);
    const std::string diff = identity_difference(stored, meta, true);
    if (!diff.empty()) {
      throw config::ScenarioError(fmt::format(
          "--resume: {} holds a different campaign: {} differ(s) (stored vs now); `--replace` "
          "(without --resume) starts afresh and replaces it, or choose another --out",
          what, diff));
    }
  };
  bool copied = false;  // a copy made here is removed again when it cannot be resumed
  if (fs::exists(partial, ec) && RunStore::holds_nothing(partial)) {
    // A campaign killed while it created its store: nothing to lose, nothing to resume from it.
    remove_store_files(partial);
    if (!fs::exists(live, ec)) {
      std::cerr << fmt::format(
          "ncosim: --resume: {} held no run (a campaign killed while creating its store): "
          "starting afresh\n",
          partial);
      return RunStore::create(partial, meta);
    }
  }
  try {
    if (!fs::exists(partial, ec)) {
      if (!fs::exists(live, ec)) {
        throw config::ScenarioError(
            fmt::format("--resume: no run store to resume in '{}' (expected {})", cmd.out, live));
      }
      // The finished set's store goes on in a copy beside the folder; the set stays as it is.
      const RunStore finished = RunStore::open(live, false);
      same_campaign(finished, live);
      finished.verify(loaded.cases.size(), run_limit(loaded, finished.meta()));
      finished.copy_to(partial);
      copied = true;
    }
    RunStore store = RunStore::open(partial, true);
    same_campaign(
        store, fmt::format("{} (the store of an unfinished campaign into '{}')", partial, cmd.out));
    store.verify(loaded.cases.size(), run_limit(loaded, store.meta()));
    return store;
  } catch (const StoreError& e) {
    if (copied) remove_store_files(partial);
    throw config::ScenarioError(fmt::format("--resume: {}", e.what()));
  } catch (...) {
    if (copied) remove_store_files(partial);
    throw;
  }
}

// The campaign's totals added to what the store holds from earlier sessions.
void record_session(RunStore& store, double wall, int used_threads, int ranks, int sig) {
  const auto m = store.meta();
  double total = wall;
  try {
    total += std::stod(m.at("wall_seconds"));
  } catch (...) {
  }
  store.set_meta("wall_seconds", fmt::format("{:.17g}", total));
  store.set_meta("threads", std::to_string(used_threads));
  store.set_meta("ranks", std::to_string(ranks));
  store.set_meta("stopped", sig > 0 ? signal_name(sig) : "");
}

// What one `run` session did, for its closing line.
struct SessionTotals {
  std::chrono::steady_clock::time_point started = std::chrono::steady_clock::now();
  double design = 0.0;  // reading, validating and designing every case (load_cases), seconds
  double wall = 0.0;    // the campaigns' simulation, seconds
  int threads = 1;
  int ranks = 1;  // MPI ranks (1 without mpirun)
  std::uint64_t simulated = 0, skipped = 0;
  std::vector<std::uint64_t> case_runs;  // per case: runs stored before and simulated now
};

// "3 cases x 20 runs x 5000 periods = 60 runs" (one case: "20 runs x 5000 periods"; cases of
// different sizes: "20..40 runs").
std::string campaign_size(const LoadedScenario& loaded,
                          const std::vector<std::uint64_t>& case_runs) {
  std::uint64_t total = 0, rlo = std::numeric_limits<std::uint64_t>::max(), rhi = 0;
  std::int64_t plo = std::numeric_limits<std::int64_t>::max(), phi = 0;
  for (std::size_t c = 0; c < loaded.cases.size(); ++c) {
    const std::uint64_t r = c < case_runs.size() ? case_runs[c] : 0;
    total += r;
    rlo = std::min(rlo, r);
    rhi = std::max(rhi, r);
    plo = std::min(plo, loaded.cases[c].scenario->run.periods);
    phi = std::max(phi, loaded.cases[c].scenario->run.periods);
  }
  auto range = [](auto lo, auto hi) {
    return lo == hi ? fmt::format("{}", lo) : fmt::format("{}..{}", lo, hi);
  };
  if (loaded.cases.size() == 1) return fmt::format("{} runs x {} periods", total, plo);
  return fmt::format("{} cases x {} runs x {} periods = {} runs", loaded.cases.size(),
                     range(rlo, rhi), range(plo, phi), total);
}

// Seconds as the closing line prints them: 2 decimals below 10 s, 1 above.
std::string seconds_text(double s) {
  return s >= 10.0 ? fmt::format("{:.1f}", s) : fmt::format("{:.2f}", s);
}

// The closing line: "ncosim: 3 cases x 20 runs x 5000 periods = 60 runs in 9.9 s: design 1.1 s,
// simulation 8.7 s on 2 threads [x 3 MPI ranks][, shard I/N]; results in DIR/", with the runs
// stored before when resumed. The first time is the command's whole (`total` seconds); the rest
// (exports, writing files) is neither design nor simulation.
std::string closing_line(const RunCommand& cmd, const LoadedScenario& loaded,
                         const SessionTotals& t, double total) {
  return fmt::format(
      "ncosim: {}{} in {} s: design {} s, simulation {} s on {} thread{}{}{}; results in {}/\n",
      campaign_size(loaded, t.case_runs),
      t.skipped > 0 ? fmt::format(" ({} stored before, {} simulated now)", t.skipped, t.simulated)
                    : "",
      seconds_text(total), seconds_text(t.design), seconds_text(t.wall), t.threads,
      t.threads == 1 ? "" : "s", t.ranks > 1 ? fmt::format(" x {} MPI ranks", t.ranks) : "",
      cmd.shard.empty() ? "" : fmt::format(", shard {}", cmd.shard), cmd.out);
}

// The runs lo..limit-1 of this shard that the store does not hold yet (`done`, sorted); the
// others are counted in `skipped`.
std::vector<std::uint64_t> runs_to_do(const std::vector<std::uint64_t>& done, std::uint64_t lo,
                                      std::uint64_t limit, const Shard& shard,
                                      std::uint64_t& skipped) {
  std::vector<std::uint64_t> todo;
  auto d = std::lower_bound(done.begin(), done.end(), lo);
  for (std::uint64_t r = lo; r < limit; ++r) {
    if (!shard.owns(r)) continue;
    while (d != done.end() && *d < r) ++d;
    if (d != done.end() && *d == r) {
      ++skipped;
      continue;
    }
    todo.push_back(r);
  }
  return todo;
}

// The summary table and closing line on stdout; the exit status (a stop signal's, or
// kExitFlagged with --fail-on-status and rows whose status is not the expected one).
int finish_session(const RunCommand& cmd, const std::string& md, const LoadedScenario& loaded,
                   const SessionTotals& t, const std::string& path, int sig, bool complete,
                   const std::vector<std::string>& not_ok) {
  std::cout << md << std::flush;
  // With --format csv|json stdout holds the data alone: the closing line goes to stderr.
  (cmd.format == "csv" || cmd.format == "json" ? std::cerr : std::cout)
      << "\n"
      << closing_line(
             cmd, loaded, t,
             std::chrono::duration<double>(std::chrono::steady_clock::now() - t.started).count());
  if (sig > 0) {
    // A signal after the last run had started stopped nothing: the results are complete (the
    // exit status still says a signal came).
    std::cerr
        << (complete
                ? fmt::format("ncosim: {} stopped nothing (every run had started): the campaign is "
                              "complete ({} run(s) committed to {})\n",
                              signal_name(sig), t.simulated, path)
                : fmt::format(
                      "ncosim: stopped by {}: {} run(s) committed to {}; partial results written; "
                      "`--resume` continues\n",
                      signal_name(sig), t.simulated, path));
    return 128 + sig;
  }
  // A run whose process died (a crash inside ns-3) is not a result of the estimators: its rows
  // (status network_failure) fail the command as --fail-on-status would, asked or not.
  const bool crashed = std::any_of(not_ok.begin(), not_ok.end(), [](const std::string& r) {
    return r.find(": network_failure") != std::string::npos;
  });
  if ((cmd.fail_on_status || crashed) && !not_ok.empty()) {
    std::string list;
    for (const auto& r : not_ok) list += "  " + r + "\n";
    // Overloaded links (sim/run/overload.h) are listed after the rows.
    const auto links = std::count_if(not_ok.begin(), not_ok.end(), [](const std::string& r) {
      return r.find(": overloaded (offered") != std::string::npos;
    });
    const auto rows = static_cast<std::ptrdiff_t>(not_ok.size()) - links;
    std::string what = fmt::format("{} row(s) with an unexpected status", rows);
    if (links > 0)
      what = rows > 0 ? fmt::format("{} and {} overloaded link(s)", what, links)
                      : fmt::format("{} overloaded link(s)", links);
    std::cerr << fmt::format("ncosim: {}: {} (results written to {}/):\n{}",
                             cmd.fail_on_status ? "--fail-on-status" : "a run's process died", what,
                             cmd.out, list);
    return kExitFlagged;
  }
  return 0;
}

// Under mpirun, the MPI session (null otherwise); throws when this build has no MPI.
std::unique_ptr<MpiSession> start_mpi() {
  if (!mpi_launched()) return nullptr;
  if (!mpi_available()) {
    throw config::ScenarioError(
        "started by mpirun with several ranks, but this ncosim was built without MPI "
        "(CMake option NCOSIM_MPI; Debian libboost-mpi-dev libopenmpi-dev)");
  }
  return std::make_unique<MpiSession>();
}

// Each case's estimator names into the store; per case, the runs it holds already (with
// --resume; none otherwise).
std::vector<std::vector<std::uint64_t>> register_cases(RunStore& store,
                                                       const LoadedScenario& loaded, bool resume) {
  std::vector<std::vector<std::uint64_t>> stored(loaded.cases.size());
  for (std::size_t c = 0; c < loaded.cases.size(); ++c) {
    std::vector<std::string> names;
    for (const auto& e : loaded.cases[c].scenario->estimators) names.push_back(e.name);
    store.put_estimators(c, names);
    if (resume) stored[c] = store.done_runs(c);
  }
  return stored;
}

// One `run` session on rank 0: the campaign's fixed inputs and what its batches accumulate.
struct RunSession {
  RunSession(const RunCommand& c, const LoadedScenario& l, const Shard& sh, const TargetRule& r,
             MpiSession* m)
      : cmd(c),
        loaded(l),
        shard(sh),
        rule(r),
        mpi(m),
        timed(l.cases.size(), 0),
        ran(l.cases.size(), 0) {
    totals.case_runs.assign(l.cases.size(), 0);
    totals.ranks = m != nullptr ? m->size() : 1;
  }

  const RunCommand& cmd;
  const LoadedScenario& loaded;
  const Shard shard;
  const TargetRule rule;
  MpiSession* const mpi;  // under mpirun, else null
  CampaignProgress* progress =
      nullptr;  // the campaign's progress line (sim/run/progress.h), or null
  std::vector<std::vector<std::uint64_t>> stored;  // per case: the runs the store held at the start
  SessionTotals totals;
  std::vector<char> timed,
      ran;  // per case: ns_per_period stored / a campaign of it ran in this session
  std::vector<TraceRow> trace;  // run 0 of the first case, with --trace
};

// The runs lo..limit-1 of case c that are still to do, simulated here or on the MPI ranks and
// pushed to the sink as they complete; ns_per_period stored once per case (unless stopped).
void run_case_batch(RunSession& session, StoreSink& sink, std::size_t c, std::uint64_t lo,
                    std::uint64_t limit) {
  const RunCommand& cmd = session.cmd;
  const std::size_t cases = session.loaded.cases.size();
  const Scenario& sc = *session.loaded.cases[c].scenario;
  const std::uint64_t skipped = session.totals.skipped;
  std::vector<std::uint64_t> todo =
      runs_to_do(session.stored[c], lo, limit, session.shard, session.totals.skipped);
  session.totals.case_runs[c] += session.totals.skipped - skipped;
  if (todo.empty()) return;
  CampaignOptions opt;
  opt.threads =
      session.mpi && cmd.threads == 0 ? 1 : cmd.threads;  // one thread per rank unless asked
  opt.trace = cmd.trace && c == 0;
  opt.time_estimators = cmd.timing && session.timed[c] == 0;
  if (session.progress != nullptr) {
    session.progress->set_case(c, cases,
                               session.rule.on() ? fmt::format("runs {}..{}", lo, limit - 1) : "");
    opt.progress = session.progress;
  }
  opt.only_runs = std::move(todo);
  opt.stop = &g_stop;
  opt.on_run = [&sink, c](std::uint64_t run, RunMetrics&& m, RunLinks&& links) {
    sink.push(c, run, std::move(m), std::move(links));
  };
  CampaignResult res = run_case(sc, c, opt, session.mpi);
  sink.flush();
  // After its runs are committed: a kill in between leaves runs that the stored curve lacks,
  // which the export simulates again (error_curve_for).
  if (!res.curve.empty()) sink.with_store([&](RunStore& s) { s.add_curve(c, res.curve); });
  session.totals.wall += res.wall_seconds;
  session.totals.threads = res.threads;
  session.totals.simulated += res.runs_done;
  session.totals.case_runs[c] += res.runs_done;
  session.ran[c] = 1;
  if (!res.trace.empty()) session.trace = std::move(res.trace);
  if (opt.time_estimators && !res.stopped) {
    session.timed[c] = 1;
    sink.with_store([&](RunStore& s) { s.put_timing(c, res.ns_per_period); });
  }
}

// --target-ci: whether the runs stored so far meet the target in every row.
bool target_decided(const RunSession& session, StoreSink& sink) {
  std::vector<CampaignResult> results(session.loaded.cases.size());
  sink.with_store([&](RunStore& s) {
    for (std::size_t c = 0; c < session.loaded.cases.size(); ++c) {
      for (auto& [run, m] : s.load_case(c)) {
        results[c].run_ids.push_back(run);
        results[c].runs.push_back(std::move(m));
      }
    }
  });
  return decide_target(session.loaded, results, session.rule).decided;
}

// Batches: the whole campaign at once, or with --target-ci fixed batches of run.runs until the
// target is met or --max-runs; a stop signal ends them between cases.
void run_batches(RunSession& session, StoreSink& sink) {
  const TargetRule& rule = session.rule;
  for (std::uint64_t lo = 0; g_stop.load() == 0;) {
    const std::uint64_t hi = rule.on() ? std::min(lo + rule.batch, rule.max_runs) : 0;
    for (std::size_t c = 0; c < session.loaded.cases.size() && g_stop.load() == 0; ++c) {
      const std::uint64_t limit =
          rule.on() ? hi : static_cast<std::uint64_t>(session.loaded.cases[c].scenario->run.runs);
      run_case_batch(session, sink, c, lo, limit);
    }
    if (!rule.on() || hi >= rule.max_runs || g_stop.load() != 0) break;
    if (session.shard.count <= 1) {  // a shard cannot decide: it runs to --max-runs, merge decides
      if (target_decided(session, sink)) break;
    }
    lo = hi;
  }
}

// After the batches: NaN timings for the cases run with --no-timing, and with --trace the
// trajectory of run 0 (simulated again when an earlier session did run 0).
void store_timing_and_trace(RunSession& session, StoreSink& sink) {
  const LoadedScenario& loaded = session.loaded;
  for (std::size_t c = 0; c < loaded.cases.size(); ++c) {
    if (!session.cmd.timing && session.ran[c] != 0) {
      const std::size_t ne = loaded.cases[c].scenario->estimators.size();
      sink.with_store([&](RunStore& s) { s.put_timing(c, std::vector<double>(ne, std::nan(""))); });
    }
  }
  if (session.cmd.trace && session.trace.empty() &&
      g_stop.load() == 0) {  // run 0 was done by an earlier session
    std::string failure;     // run 0's network died: no trace (its rows say network_failure)
    campaign_run(*loaded.cases.front().scenario, 0, nullptr, nullptr, failure, &session.trace);
    if (!failure.empty())
      std::cerr << fmt::format("ncosim: run 0: the replay for the trace: {}; no trajectory.csv\n",
                               failure);
  }
  if (session.cmd.trace && !session.trace.empty()) {
    const std::string csv = trajectory_csv(*loaded.cases.front().scenario, session.trace);
    sink.with_store([&](RunStore& s) { s.put_artifact("trajectory.csv", csv); });
  }
}

// The campaign's runs over every case (this shard's; with --target-ci up to --max-runs per case,
// an upper bound) and how many of them the store held at the start, for the progress line.
void set_progress_total(const RunSession& session, CampaignProgress& progress) {
  const Shard& shard = session.shard;
  std::uint64_t total = 0, stored = 0;
  for (std::size_t c = 0; c < session.loaded.cases.size(); ++c) {
    const std::uint64_t limit =
        session.rule.on() ? session.rule.max_runs
                          : static_cast<std::uint64_t>(session.loaded.cases[c].scenario->run.runs);
    total += limit / shard.count + (shard.index < limit % shard.count ? 1 : 0);
    for (std::uint64_t r : session.stored[c]) stored += r < limit && shard.owns(r) ? 1 : 0;
  }
  progress.set_total(total, stored, session.rule.on());
}

// Simulates the session's runs into the store, committed by a writer thread as they complete.
void simulate_session(RunSession& session, RunStore& store) {
  StoreSink sink(store);
  run_batches(session, sink);
  store_timing_and_trace(session, sink);
  sink.finish();
}

}  // namespace

int cmd_run_campaign(const RunCommand& cmd) {
  const auto started = std::chrono::steady_clock::now();
  const Shard shard = cmd.shard.empty() ? Shard{} : parse_shard(cmd.shard);
  check_target_options(cmd);
  LoadedScenario loaded = load_cases(cmd.file, cmd.sets, cmd.overrides);
  const double design =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  reference_case_index(loaded);  // [paired] reference_case: bad input before t = 0
  const std::string& out = cmd.out;
  auto meta =
      campaign_meta(loaded, cmd.overrides,
                    cmd.shard.empty() ? "" : fmt::format("{}/{}", shard.index + 1, shard.count));
  const TargetRule rule = target_rule(cmd, loaded, meta);
  // sim/present/table_view.h: bad --columns before t = 0; the table fits COLUMNS or the terminal.
  const TableRequest table{cmd.columns, cmd.format,
                           table_width(std::getenv("COLUMNS"), STDOUT_FILENO)};
  check_table_request(
      table, summary_csv_columns(loaded.sweeps, loaded.cases.front().scenario->model.plant.n(),
                                 rule.on()));
  // Under mpirun: ranks > 0 simulate what rank 0 hands out; rank 0 goes on alone from here.
  const std::unique_ptr<MpiSession> mpi = start_mpi();
  if (mpi && mpi->rank() > 0) {
    std::vector<const Scenario*> cases;
    for (const auto& c : loaded.cases) cases.push_back(c.scenario.get());
    mpi->serve(cases);
    return 0;
  }
  const OutputFolderLock folder_lock(
      out);                 // sim/files/output_set.h: one writer per folder for the whole campaign
  prepare_output_dir(out);  // fail before the campaign, not after it
  {
    const Scenario& sc0 =
        *loaded.cases.front()
             .scenario;  // sim/scenario/resource_limits.h: the exports hold every run
    check_campaign_resources(loaded.file, 0, sc0.run.runs, loaded.cases.size(),
                             sc0.estimators.size(), sc0.model.plant.n(), sc0.model.sensors.size());
  }
  RunStore store = open_run_store(cmd, loaded, meta);
  const std::string path = store_path(out);
  RunSession session(cmd, loaded, shard, rule, mpi.get());
  session.totals.started = started;
  session.totals.design = design;
  session.stored = register_cases(store, loaded, cmd.resume);

  // One progress line for the whole campaign: redrawn on a terminal, a line every 5 s in a log.
  const auto progress_ptr =
      cmd.progress_observer
          ? std::make_unique<CampaignProgress>(cmd.progress_observer)
          : std::make_unique<CampaignProgress>(cmd.quiet     ? CampaignProgress::Mode::off
                                               : ::isatty(2) ? CampaignProgress::Mode::terminal
                                                             : CampaignProgress::Mode::log);
  CampaignProgress& progress = *progress_ptr;
  set_progress_total(session, progress);
  session.progress = &progress;
  progress.start();
  const StopSignals signals(cmd.second_signal_aborts);
  simulate_session(session, store);
  progress.finish();
  // Test hook: a signal that comes after the last run (a moment the signal tests cannot aim at).
  if (const char* raise_after = std::getenv("NCOSIM_TEST_RAISE_AFTER_RUNS"))
    ::raise(std::atoi(raise_after));
  const int sig = g_stop.load();
  record_session(store, session.totals.wall, session.totals.threads, session.totals.ranks, sig);
  ExportInfo info;
  info.command_line = cmd.command_line;
  info.stopped = sig > 0 ? signal_name(sig) : "";
  std::vector<std::string> not_ok;
  info.not_ok = &not_ok;
  bool complete = false;
  info.complete = &complete;
  info.table = &table;
  const std::string md = export_and_install(loaded, store, out, info);
  return finish_session(cmd, md, loaded, session.totals, path, sig, complete, not_ok);
}

}  // namespace ncosim::sim
