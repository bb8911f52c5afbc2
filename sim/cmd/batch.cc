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
#include "sim/files/output_set.h"
#include "sim/present/table_view.h"
#include "sim/run/campaign.h"
#include "sim/run/link_report.h"
#include "sim/run/progress.h"
#include "sim/scenario/resource_limits.h"
#include "sim/store/store.h"

namespace ncosim::sim {

namespace {

// Set by SIGINT/SIGTERM (the signal number) or by a failing store writer (-1): no new run starts.
std::atomic<int> g_stop{0};
static_assert(std::atomic<int>::is_always_lock_free,
              "the stop flag is written from a signal handler");

extern "C" void on_stop_signal(int sig) {
  g_stop.store(sig);
  static const char msg[] =
      "\nncosim: stopping: no new run starts; the runs in progress finish and are committed "
      "(a second signal aborts at once)\n";
  const ssize_t ignored = ::write(2, msg, sizeof msg - 1);
  (void)ignored;
}

// SIGINT/SIGTERM handlers for the duration of a campaign; the first signal restores the
// default action (SA_RESETHAND), so a second one ends the process at once.
class StopSignals {
 public:
  StopSignals() {
    g_stop.store(0);
    struct sigaction sa {};
    sa.sa_handler = on_stop_signal;
    sigemptyset(&sa.sa_mask);
    sa.sa_flags = SA_RESETHAND;
    sigaction(SIGINT, &sa, &old_int_);
    sigaction(SIGTERM, &sa, &old_term_);
  }
  ~StopSignals() {
    sigaction(SIGINT, &old_int_, nullptr);
    sigaction(SIGTERM, &old_term_, nullptr);
  }
  StopSignals(const StopSignals&) = delete;
  StopSignals& operator=(const StopSignals&) = delete;

 private:
  struct sigaction old_int_ {};
  struct sigaction old_term_ {};
};

std::string signal_name(int sig) {
  if (sig == SIGINT) return "SIGINT";
  if (sig == SIGTERM) return "SIGTERM";
  return fmt::format("signal {}", sig);
}

// Commits completed runs from a writer thread: every 250 ms, one transaction for all runs
// completed since the last commit. The store is used by one thread at a time (`with_store`).
class StoreSink {
 public:
  explicit StoreSink(RunStore& store)
      : store_(store), interval_(commit_interval()), thread_([this] { loop(); }) {}
  ~StoreSink() {
    try {
      finish();
    } catch (...) {  // reported by the explicit finish() of a normal exit
    }
  }
  StoreSink(const StoreSink&) = delete;
  StoreSink& operator=(const StoreSink&) = delete;

  void push(std::size_t case_index, std::uint64_t run, RunMetrics&& m, RunLinks&& links) {
    std::lock_guard<std::mutex> lock(mutex_);
    pending_.push_back(StoredRun{case_index, run, std::move(m), std::move(links)});
  }
  // Commits everything pushed so far; rethrows a writer failure.
  void flush() {
    commit_pending();
    rethrow();
  }
  template <class F>
  void with_store(F f) {
    std::lock_guard<std::mutex> lock(db_mutex_);
    f(store_);
  }
  void finish() {
    if (thread_.joinable()) {
      {
        std::lock_guard<std::mutex> lock(mutex_);
        done_ = true;
      }
      cv_.notify_all();
      thread_.join();
    }
    flush();
  }

 private:
  void loop() {
    std::unique_lock<std::mutex> lock(mutex_);
    while (!done_) {
      cv_.wait_for(lock, interval_, [&] { return done_; });
      lock.unlock();
      commit_pending();
      lock.lock();
    }
  }
  void commit_pending() {
    std::lock_guard<std::mutex> db(db_mutex_);
    std::vector<StoredRun> batch;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      batch.swap(pending_);
    }
    if (batch.empty() || error_) return;
    try {
      store_.put_runs(batch);
    } catch (...) {
      error_ = std::current_exception();
      int expected = 0;
      g_stop.compare_exchange_strong(expected, -1);
    }
  }
  void rethrow() {
    std::lock_guard<std::mutex> db(db_mutex_);
    if (error_) std::rethrow_exception(error_);
  }

  // 250 ms; NCOSIM_TEST_COMMIT_MS (tests only: 1..1000) shortens it so that a kill test finds
  // committed batches inside a short campaign on a fast machine.
  static std::chrono::milliseconds commit_interval() {
    if (const char* v = std::getenv("NCOSIM_TEST_COMMIT_MS")) {
      char* end = nullptr;
      const long ms = std::strtol(v, &end, 10);
      if (end != v && *end == '\0' && ms >= 1 && ms <= 1000) return std::chrono::milliseconds(ms);
    }
    return std::chrono::milliseconds(250);
  }

  RunStore& store_;
  std::chrono::milliseconds interval_;
  std::mutex mutex_, db_mutex_;
  std::condition_variable cv_;
  std::vector<StoredRun> pending_;
  bool done_ = false;
  std::exception_ptr error_;
  std::thread thread_;
};

std::string json_text(const nlohmann::json& j) { return j.dump(); }

// The campaign table of a new store.
std::map<std::string, std::string> campaign_meta(const LoadedScenario& loaded,
                                                 const RunOverrides& ov, const std::string& shard) {
  std::error_code ec;
  const auto abs = std::filesystem::absolute(loaded.file, ec);
  const Scenario& sc = *loaded.cases.front().scenario;
  nlohmann::json inputs = nlohmann::json::object();
  for (const auto& [file, hash] : loaded.inputs) inputs[file] = hash;
  return {
      // "format" is the store's own (RunStore::kFormat, written by RunStore::create).
      {"scenario_file", loaded.file},
      {"scenario_path", ec ? loaded.file : abs.lexically_normal().string()},
      {"scenario_text", loaded.text},
      {"scenario_hash", loaded.hash},
      {"inputs", json_text(inputs)},  // every file the scenario read: path -> content hash
      {"overrides", json_text(loaded.overrides)},
      {"override_runs", ov.runs > 0 ? std::to_string(ov.runs) : ""},
      {"override_periods", ov.periods > 0 ? std::to_string(ov.periods) : ""},
      {"override_seed", ov.seed ? std::to_string(*ov.seed) : ""},
      {"seed", std::to_string(sc.run.seed)},
      {"runs", std::to_string(sc.run.runs)},
      {"periods", std::to_string(sc.run.periods)},
      {"cases", std::to_string(loaded.cases.size())},
      {"ncosim_version", NCOSIM_VERSION},
      {"git_commit", NCOSIM_GIT_COMMIT},
      {"shard", shard},
      {"target_ci", ""},
      {"max_runs", ""},
      {"wall_seconds", "0"},
      {"threads", "1"},
  };
}

// The input files (campaign table `inputs`: a JSON object path -> content hash) that differ
// between two campaigns, named with both hashes; "" when none.
std::string input_files_difference(const std::string& a, const std::string& b) {
  auto parse = [](const std::string& text) {
    std::map<std::string, std::string> m;
    if (text.empty()) return m;  // a store written before inputs were recorded
    const nlohmann::json j = nlohmann::json::parse(text);
    for (auto it = j.begin(); it != j.end(); ++it) m[it.key()] = it.value().get<std::string>();
    return m;
  };
  const auto ma = parse(a), mb = parse(b);
  std::vector<std::string> out;
  for (const auto& [file, ha] : ma) {
    const auto it = mb.find(file);
    if (it == mb.end()) {
      out.push_back(fmt::format("the input file '{}' (read by one campaign only)", file));
    } else if (it->second != ha) {
      out.push_back(
          fmt::format("the content of the input file '{}' (hash {} vs {})", file, ha, it->second));
    }
  }
  for (const auto& [file, hb] : mb) {
    if (ma.count(file) == 0)
      out.push_back(fmt::format("the input file '{}' (read by one campaign only)", file));
  }
  std::string text;
  for (std::size_t i = 0; i < out.size(); ++i) text += (i ? ", " : "") + out[i];
  return text.empty() ? "the input files" : text;
}

// The keys that define a campaign's identity, with how to name them in a refusal.
const std::vector<std::pair<std::string, std::string>>& identity_keys() {
  static const std::vector<std::pair<std::string, std::string>> keys{
      {"scenario_text", "the scenario text"},
      {"inputs", "the input files"},
      {"overrides", "the --set overrides"},
      {"override_runs", "--runs"},
      {"override_periods", "--periods"},
      {"override_seed", "--seed"},
      {"ncosim_version", "the ncosim version"},
      {"git_commit", "the ncosim binary (git commit)"},
      {"target_ci", "--target-ci"},
      {"max_runs", "--max-runs"},
  };
  return keys;
}

// Empty when `a` and `b` are the same campaign; else what differs.
std::string identity_difference(const std::map<std::string, std::string>& a,
                                const std::map<std::string, std::string>& b, bool with_shard) {
  auto get = [](const std::map<std::string, std::string>& m, const std::string& k) {
    const auto it = m.find(k);
    return it == m.end() ? std::string() : it->second;
  };
  std::vector<std::string> diffs;
  auto keys = identity_keys();
  if (with_shard) keys.emplace_back("shard", "--shard");
  for (const auto& [key, name] : keys) {
    const std::string va = get(a, key), vb = get(b, key);
    if (va == vb) continue;
    if (key == "scenario_text") {
      diffs.push_back(fmt::format("{} (hash {} vs {})", name, get(a, "scenario_hash"),
                                  get(b, "scenario_hash")));
    } else if (key == "inputs") {
      diffs.push_back(input_files_difference(va, vb));
    } else {
      diffs.push_back(fmt::format("{} ('{}' vs '{}')", name, va, vb));
    }
  }
  std::string out;
  for (std::size_t i = 0; i < diffs.size(); ++i) out += (i ? ", " : "") + diffs[i];
  return out;
}

// Checks every field of a store's campaign table that the commands read, so that a damaged or
// hand-edited table is refused with the field's name (StoreError) instead of a bare parser
// exception or a silently different campaign.
void check_campaign_meta(const std::map<std::string, std::string>& meta, const std::string& path) {
  auto bad = [&](const std::string& key, const std::string& expected) {
    const auto it = meta.find(key);
    std::string got = it == meta.end() ? std::string("nothing (the field is missing)")
                                       : fmt::format("'{}'", it->second.substr(0, 60));
    if (it != meta.end() && it->second.size() > 60) got += "...";
    return StoreError(fmt::format(
        "run store '{}': campaign field '{}': expected {}, got {} (the store is damaged or "
        "was edited; re-run the campaign)",
        path, key, expected, got));
  };
  auto text = [&](const std::string& key) -> const std::string& {
    const auto it = meta.find(key);
    if (it == meta.end()) throw bad(key, "a value");
    return it->second;
  };
  auto whole = [&](const std::string& key, std::uint64_t min, bool optional) {
    const auto it = meta.find(key);
    if (it == meta.end() || it->second.empty()) {
      if (optional) return;
      throw bad(key, fmt::format("a whole number >= {}", min));
    }
    std::uint64_t v = 0;
    const auto& t = it->second;
    const auto r = std::from_chars(t.data(), t.data() + t.size(), v);
    if (r.ec != std::errc() || r.ptr != t.data() + t.size() || v < min) {
      throw bad(key, fmt::format("{}a whole number >= {}", optional ? "empty or " : "", min));
    }
  };
  auto json_of = [&](const std::string& key, bool optional, auto&& ok, const char* expected) {
    const auto it = meta.find(key);
    if (it == meta.end()) {
      if (optional) return;
      throw bad(key, expected);
    }
    if (optional && it->second.empty()) return;
    const auto j = nlohmann::json::parse(it->second, nullptr, false);
    if (j.is_discarded() || !ok(j)) throw bad(key, expected);
  };
  auto strings = [](const nlohmann::json& j) {
    if (!j.is_array()) return false;
    return std::all_of(j.begin(), j.end(), [](const nlohmann::json& e) { return e.is_string(); });
  };
  for (const char* key :
       {"scenario_file", "scenario_path", "scenario_text", "ncosim_version", "git_commit"}) {
    (void)text(key);
  }
  const std::string& hash = text("scenario_hash");
  if (hash.size() != 16 || hash.find_first_not_of("0123456789abcdef") != std::string::npos) {
    throw bad("scenario_hash", "16 hexadecimal digits");
  }
  whole("seed", 0, false);
  whole("runs", 1, false);
  whole("periods", 1, false);
  whole("cases", 1, false);
  whole("override_runs", 1, true);
  whole("override_periods", 1, true);
  whole("override_seed", 0, true);
  whole("max_runs", 1, true);
  for (const char* key : {"threads", "ranks"}) {  // absent in stores of older versions, never empty
    if (meta.count(key) != 0) whole(key, 1, false);
  }
  json_of("overrides", false, strings, "a JSON array of strings (the --set overrides)");
  json_of("merged_from", true, strings, "a JSON array of folder names");
  json_of(
      "inputs", true,
      [](const nlohmann::json& j) {
        if (!j.is_object()) return false;
        return std::all_of(j.begin(), j.end(),
                           [](const nlohmann::json& v) { return v.is_string(); });
      },
      "a JSON object of input file -> content hash");
  auto number = [&](const std::string& key, bool optional, double lo, double hi,
                    const char* expected) {
    const auto it = meta.find(key);
    if (it == meta.end() || it->second.empty()) {
      if (optional) return;
      throw bad(key, expected);
    }
    double v = 0.0;
    const auto& t = it->second;
    const auto r = std::from_chars(t.data(), t.data() + t.size(), v);
    if (r.ec != std::errc() || r.ptr != t.data() + t.size() || !std::isfinite(v) || v < lo ||
        v > hi) {
      throw bad(key, expected);
    }
  };
  number("wall_seconds", true, 0.0, std::numeric_limits<double>::max(),
         "a finite number of seconds >= 0");
  number("target_ci", true, std::numeric_limits<double>::min(), 1.0 - 1e-16,
         "empty or a number in (0, 1)");
  if (const auto it = meta.find("shard"); it != meta.end() && !it->second.empty()) {
    try {
      (void)parse_shard(it->second);
    } catch (const ScenarioError&) {
      throw bad("shard", "empty or I/N with 1 <= I <= N");
    }
  }
}

RunOverrides overrides_of(const std::map<std::string, std::string>& meta) {
  RunOverrides ov;
  auto num = [&](const char* key) -> std::optional<std::uint64_t> {
    const auto it = meta.find(key);
    if (it == meta.end() || it->second.empty()) return std::nullopt;
    return std::stoull(it->second);
  };
  if (auto v = num("override_runs")) ov.runs = static_cast<std::int64_t>(*v);
  if (auto v = num("override_periods")) ov.periods = static_cast<std::int64_t>(*v);
  ov.seed = num("override_seed");
  return ov;
}

// The scenario of a store, rebuilt from its text (designs included); `path` names the store in
// messages. The campaign table is checked first (check_campaign_meta), then that the text gives
// the stored hash, runs, periods, seed and cases, and that every input file it reads still has the
// content the campaign read. Throws StoreError on a damaged store, ScenarioError otherwise.
LoadedScenario reload(const std::map<std::string, std::string>& meta, const std::string& path) {
  check_campaign_meta(meta, path);
  const auto sets = nlohmann::json::parse(meta.at("overrides")).get<std::vector<std::string>>();
  LoadedScenario loaded;
  try {
    loaded = load_cases_text(meta.at("scenario_path"), meta.at("scenario_text"), sets,
                             overrides_of(meta));
  } catch (const ScenarioError& e) {
    // The text is the store's, not the file's on disk (which may have changed since).
    throw ScenarioError(
        fmt::format("run store '{}': the scenario text stored in it (of {}) does not load: {}",
                    path, meta.at("scenario_file"), e.what()));
  }
  loaded.file = meta.at("scenario_file");
  const Scenario& sc = *loaded.cases.front().scenario;
  const std::pair<const char*, std::string> derived[] = {
      {"scenario_hash", loaded.hash},
      {"runs", std::to_string(sc.run.runs)},
      {"periods", std::to_string(sc.run.periods)},
      {"seed", std::to_string(sc.run.seed)},
      {"cases", std::to_string(loaded.cases.size())}};
  for (const auto& [key, value] : derived) {
    if (meta.at(key) != value) {
      throw StoreError(fmt::format(
          "run store '{}': campaign field '{}' is '{}' but its stored scenario text and "
          "options give '{}' (the store is damaged or was edited; re-run the campaign)",
          path, key, meta.at(key), value));
    }
  }
  if (const auto it = meta.find("inputs"); it != meta.end()) {
    nlohmann::json now = nlohmann::json::object();
    for (const auto& [file, h] : loaded.inputs) now[file] = h;
    if (json_text(now) != it->second) {
      throw ScenarioError(
          fmt::format("run store '{}': {} changed since the campaign ran; restore it to use this "
                      "store (the exports would describe other inputs than the runs had)",
                      path, input_files_difference(it->second, json_text(now))));
    }
  }
  return loaded;
}

Shard shard_of(const std::map<std::string, std::string>& meta) {
  const auto it = meta.find("shard");
  return it == meta.end() || it->second.empty() ? Shard{} : parse_shard(it->second);
}

std::uint64_t owned_runs(const Scenario& sc, const Shard& shard) {
  const auto runs = static_cast<std::uint64_t>(sc.run.runs);
  if (shard.count <= 1) return runs;
  return runs / shard.count + (shard.index < runs % shard.count ? 1 : 0);
}

// --target-ci: runs in fixed batches of run.runs in run-index order until every row's relative
// 95 % CI half-width of mse is at most `rel`, or --max-runs. The decision depends on the runs
// 0 .. n-1 alone, so it is the same for any threads, shards or ranks.
struct TargetRule {
  double rel = 0.0;
  std::uint64_t max_runs = 0;
  std::uint64_t batch = 0;
  bool on() const { return rel > 0.0; }
};

// Fewer runs than this never stop a campaign: a CI from a handful of runs is itself too noisy.
constexpr std::uint64_t kTargetMinRuns = 20;

TargetRule target_of(const std::map<std::string, std::string>& meta, const LoadedScenario& loaded) {
  TargetRule t;
  const auto it = meta.find("target_ci");
  if (it == meta.end() || it->second.empty()) return t;
  t.rel = std::stod(it->second);
  t.max_runs = std::stoull(meta.at("max_runs"));
  t.batch = static_cast<std::uint64_t>(loaded.cases.front().scenario->run.runs);
  return t;
}

struct TargetDecision {
  bool decided = false;
  std::uint64_t runs = 0;              // runs per case the exports use (when decided)
  std::string reason;                  // "target_ci" or "max_runs"
  std::vector<std::vector<char>> met;  // [case][estimator]: 1 met, 0 not met, 2 excluded
};

// Whether each row meets the target on the first n runs of each case.
std::vector<std::vector<char>> target_met(const LoadedScenario& loaded,
                                          const std::vector<CampaignResult>& results,
                                          std::uint64_t n, double rel) {
  std::vector<std::vector<char>> met(loaded.cases.size());
  for (std::size_t c = 0; c < loaded.cases.size(); ++c) {
    const Scenario& sc = *loaded.cases[c].scenario;
    for (std::size_t e = 0; e < sc.estimators.size(); ++e) {
      if (sc.estimators[e].design->report().status != "ok") {
        met[c].push_back(2);  // a failed design has no mse to wait for
        continue;
      }
      std::vector<double> v;
      v.reserve(n);
      bool diverged = false;
      for (std::uint64_t r = 0; r < n; ++r) {
        const EstimatorRunMetrics& m = results[c].runs[r][e];
        if (m.diverged || m.count == 0) {
          diverged = true;
          break;
        }
        v.push_back(m.sse / static_cast<double>(m.count));
      }
      if (diverged) {
        met[c].push_back(2);  // no finite mse: summary.csv leaves it empty, nothing to wait for
        continue;
      }
      double sum = 0.0, largest = 0.0;
      for (double x : v) {
        sum += x;
        largest = std::max(largest, x);
      }
      const double mean = sum / static_cast<double>(v.size());
      const auto ci = ci95_half_width(v);
      const bool ci_ok = ci && (mean > 0.0 ? *ci / mean <= rel : *ci == 0.0);
      // Heavy-tail guard: no single run may carry more than `rel` of the sum, i.e. leaving out
      // any one run moves the mean by at most the target. A heavy-tailed row whose rare large
      // runs have not shown up yet has a deceptively small sample variance; this keeps it
      // running until one run can no longer dominate.
      const bool share_ok = sum > 0.0 ? largest / sum <= rel : true;
      met[c].push_back(n >= kTargetMinRuns && ci_ok && share_ok ? 1 : 0);
    }
  }
  return met;
}

TargetDecision decide_target(const LoadedScenario& loaded,
                             const std::vector<CampaignResult>& results, const TargetRule& rule) {
  std::uint64_t avail = std::numeric_limits<std::uint64_t>::max();
  for (const auto& res : results) {
    std::uint64_t i = 0;
    while (i < res.run_ids.size() && res.run_ids[i] == i) ++i;
    avail = std::min(avail, i);
  }
  TargetDecision d;
  for (std::uint64_t n = std::min(rule.batch, rule.max_runs);;
       n = std::min(n + rule.batch, rule.max_runs)) {
    if (n > avail) return d;
    d.met = target_met(loaded, results, n, rule.rel);
    bool all = true;
    for (const auto& row : d.met) {
      for (char m : row) all = all && m != 0;
    }
    if (all || n == rule.max_runs) {
      d.decided = true;
      d.runs = n;
      d.reason = all ? "target_ci" : "max_runs";
      return d;
    }
  }
}

// The link counters of every stored run, into each case's CampaignResult::link_runs (aligned
// with its runs). Complete when every run has them; else link_runs are left empty.
struct LinkCoverage {
  bool complete = true;
  std::size_t present = 0, missing = 0;
};

LinkCoverage load_link_runs(const RunStore& store, std::vector<CampaignResult>& results) {
  LinkCoverage cov;
  for (std::size_t c = 0; c < results.size(); ++c) {
    CampaignResult& res = results[c];
    auto stored = store.load_case_links(c);
    std::size_t j = 0;
    res.link_runs.reserve(res.run_ids.size());
    for (const std::uint64_t run : res.run_ids) {
      while (j < stored.size() && stored[j].first < run) ++j;
      if (j < stored.size() && stored[j].first == run) {
        res.link_runs.push_back(std::move(stored[j].second));
        ++cov.present;
      } else {
        res.link_runs.emplace_back();
        ++cov.missing;
      }
    }
  }
  cov.complete = cov.missing == 0;
  if (!cov.complete) {
    for (auto& res : results) res.link_runs.clear();
  }
  return cov;
}

struct ExportInfo {
  std::string command_line;
  std::string stopped;  // why the campaign stopped early ("" when it did not)
  std::vector<std::string>* not_ok =
      nullptr;               // receives "case, \"estimator\": status" of rows not as expected
  bool* complete = nullptr;  // receives manifest.json's `complete`
  const TableRequest* table =
      nullptr;  // `run`: the markdown out-parameter receives its stdout table
};

// The stored error curve of case c restricted to the runs the exports use: runs that the stored
// curve lacks (a campaign killed between committing its runs and its curve) are simulated again
// (the realisations are a function of the seed and run index); a curve that holds runs beyond
// them (--target-ci's stopping point) is rebuilt from those runs alone.
ErrorCurve error_curve_for(const LoadedScenario& loaded, const RunStore& store, std::size_t c,
                           const CampaignResult& res) {
  const Scenario& sc = *loaded.cases[c].scenario;
  ErrorCurve curve = store.curve(c);
  if (!curve.empty() &&
      (curve.periods() != sc.run.periods || curve.estimators() != sc.estimators.size() ||
       curve.states() != sc.model.plant.n())) {
    throw StoreError(fmt::format(
        "run store {}: the error curve of case {} has {} periods x {} estimators x {} states, "
        "the scenario {} x {} x {}",
        store.path(), c + 1, curve.periods(), curve.estimators(), curve.states(), sc.run.periods,
        sc.estimators.size(), sc.model.plant.n()));
  }
  std::vector<std::uint64_t> covered = curve.runs();
  std::sort(covered.begin(), covered.end());
  std::vector<std::uint64_t> used = res.run_ids;
  std::sort(used.begin(), used.end());
  if (!std::includes(used.begin(), used.end(), covered.begin(), covered.end())) {
    curve = ErrorCurve();
    covered.clear();
  }
  std::vector<std::uint64_t> missing;
  std::set_difference(used.begin(), used.end(), covered.begin(), covered.end(),
                      std::back_inserter(missing));
  if (!missing.empty()) {  // on every core, as a campaign of those runs
    CampaignOptions opt;
    opt.time_estimators = false;
    opt.link_counters = false;
    opt.only_runs = std::move(missing);
    opt.on_run = [](std::uint64_t, RunMetrics&&, RunLinks&&) {};
    curve.merge(run_campaign(sc, opt).curve);
  }
  return curve;
}

// Every export of the store, built by the functions of sim/analysis/output.h from the stored runs.
std::vector<std::pair<std::string, std::string>> derive_exports(const LoadedScenario& loaded,
                                                                const RunStore& store,
                                                                const ExportInfo& info,
                                                                std::string* markdown) {
  const auto meta = store.meta();
  const Shard shard = shard_of(meta);
  const TargetRule rule = target_of(meta, loaded);
  std::vector<CampaignResult> results(loaded.cases.size());
  std::vector<SummaryRow> rows;
  std::uint64_t done = 0, expected = 0;
  for (std::size_t c = 0; c < loaded.cases.size(); ++c) {
    CampaignResult& res = results[c];
    for (auto& [run, m] : store.load_case(c)) {
      res.run_ids.push_back(run);
      res.runs.push_back(std::move(m));
    }
  }
  // Link counters: links.csv needs them for every run the exports use (sim/run/link_report.h).
  const LinkCoverage links = load_link_runs(store, results);
  TargetDecision decision;
  if (rule.on() && shard.count <= 1) {
    decision = decide_target(loaded, results, rule);
    if (decision.decided) {  // runs beyond the stopping point (e.g. of shards) are not used
      for (auto& res : results) {
        res.runs.resize(decision.runs);
        res.run_ids.resize(decision.runs);
        if (!res.link_runs.empty()) res.link_runs.resize(decision.runs);
      }
    }
  }
  for (std::size_t c = 0; c < loaded.cases.size(); ++c) {
    const Scenario& sc = *loaded.cases[c].scenario;
    CampaignResult& res = results[c];
    res.ns_per_period = store.timing(c, sc.estimators.size());
    done += res.runs.size();
    if (decision.decided) {
      expected += decision.runs;
    } else if (rule.on()) {
      expected += shard.count <= 1 ? rule.max_runs
                                   : rule.max_runs / shard.count +
                                         (shard.index < rule.max_runs % shard.count ? 1 : 0);
    } else {
      expected += owned_runs(sc, shard);
    }
    auto case_rows = summarise(sc, res, loaded.cases[c].labels);
    for (std::size_t e = 0; e < case_rows.size(); ++e) {
      if (!decision.decided) continue;
      case_rows[e].stop = decision.reason;
      if (decision.met[c][e] == 0 && case_rows[e].status == "ok")
        case_rows[e].status = "ci_target_not_met";
    }
    rows.insert(rows.end(), case_rows.begin(), case_rows.end());
  }
  add_paired_across_cases(rows, loaded, reference_case_index(loaded));  // sim/analysis/paired.h
  if (info.not_ok != nullptr) {
    for (const auto& r : rows) {
      if (status_as_expected(r.status, r.expected_status))
        continue;  // [[estimator]] expected_status
      std::string where;
      for (std::size_t i = 0; i < r.sweep_labels.size(); ++i) {
        where += fmt::format("{} = {}, ", loaded.sweeps[i].key, r.sweep_labels[i]);
      }
      info.not_ok->push_back(fmt::format("{}\"{}\": {}", where, r.estimator, status_text(r)));
    }
  }
  const Scenario& first = *loaded.cases.front().scenario;
  const Eigen::Index n = first.model.plant.n();
  std::vector<std::vector<std::string>> labels;
  std::vector<const Scenario*> scs;
  std::vector<const CampaignResult*> res;
  for (std::size_t c = 0; c < loaded.cases.size(); ++c) {
    labels.push_back(loaded.cases[c].labels);
    scs.push_back(loaded.cases[c].scenario.get());
    res.push_back(&results[c]);
  }
  const bool complete = decision.decided || (!rule.on() && done == expected);
  if (info.complete != nullptr) *info.complete = complete;
  const std::string table_md = summary_markdown(first.title, loaded.sweeps, rows, n);
  std::string extras = consistency_notes(loaded.sweeps, rows);  // the lines under the table
  if (decision.decided) {
    extras += decision.reason == "target_ci"
                  ? fmt::format(
                        "\nStopped at {} runs per case: every row's 95 % CI half-width of mse is "
                        "within {:g} % of "
                        "its mean (`--target-ci {:g}`, batches of {}).\n",
                        decision.runs, 100.0 * rule.rel, rule.rel, rule.batch)
                  : fmt::format(
                        "\nStopped at `--max-runs {}`: the rows with status `ci_target_not_met` "
                        "did not reach "
                        "the 95 % CI half-width target of {:g} % of mse (`--target-ci {:g}`).\n",
                        decision.runs, 100.0 * rule.rel, rule.rel);
  }
  if (!complete || shard.count > 1) {
    extras += fmt::format(
        "\n**Partial results**: {} of {} runs{}{}.\n", done, expected,
        shard.count > 1 ? fmt::format(" of shard {}/{}", shard.index + 1, shard.count) : "",
        info.stopped.empty() ? "" : fmt::format(" (stopped by {})", info.stopped));
    if (!complete)
      extras += "`ncosim run FILE --out DIR --resume` (same options) runs the missing ones.\n";
    if (shard.count > 1)
      extras += "`ncosim merge OUT DIR...` combines the shards' stores into the whole campaign.\n";
  }
  const std::string md = table_md + extras;
  double wall = 0.0;
  int threads = 1;
  try {
    wall = std::stod(meta.at("wall_seconds"));
    threads = std::stoi(meta.at("threads"));
  } catch (...) {
  }
  nlohmann::json man = campaign_manifest(loaded, info.command_line, threads, wall);
  man["store"] = "runs.sqlite";
  if (const auto it = meta.find("inputs"); it != meta.end() && !it->second.empty()) {
    man["inputs"] =
        nlohmann::json::parse(it->second);  // every file the scenario read: path -> content hash
  }
  man["ranks"] = meta.count("ranks") != 0 ? std::stoi(meta.at("ranks")) : 1;
  man["runs_done"] = done;
  man["runs_expected"] = expected;
  man["complete"] = complete;
  man["stopped"] = info.stopped.empty() ? nlohmann::json(nullptr) : nlohmann::json(info.stopped);
  man["shard"] = shard.count > 1 ? nlohmann::json(meta.at("shard")) : nlohmann::json(nullptr);
  if (rule.on()) {
    man["target_ci"] = {
        {"rel", rule.rel},
        {"max_runs", rule.max_runs},
        {"batch", rule.batch},
        {"runs", decision.decided ? nlohmann::json(decision.runs) : nlohmann::json(nullptr)},
        {"stop", decision.decided ? nlohmann::json(decision.reason) : nlohmann::json(nullptr)}};
  }
  if (!links.complete) {
    man["links_csv"] = fmt::format(
        "not written: {} of the {} stored runs have no link counters (a store written "
        "before ncosim counted them)",
        links.missing, links.missing + links.present);
  }
  std::vector<std::pair<std::string, std::string>> files{
      {"summary.csv", summary_csv(loaded.sweeps, rows, n)},
      {"summary.md", md},
      {"runs.csv", runs_csv(loaded.sweeps, labels, scs, res)},
      {"transmissions.csv", transmissions_csv(loaded.sweeps, labels, scs, res)},
      {"design.json", design_json(loaded).dump(2) + "\n"},
      {"manifest.json", man.dump(2) + "\n"},
  };
  if (links.complete) files.emplace_back("links.csv", links_csv(loaded.sweeps, labels, scs, res));
  const auto art = store.artifacts();
  if (const auto it = art.find("trajectory.csv"); it != art.end())
    files.emplace_back("trajectory.csv", it->second);
  const std::string confusion = confusion_csv(loaded.sweeps, rows);
  if (confusion.find('\n') + 1 < confusion.size()) files.emplace_back("confusion.csv", confusion);
  if (first.run.error_curve) {
    std::vector<ErrorCurve> curves;
    for (std::size_t c = 0; c < loaded.cases.size(); ++c)
      curves.push_back(error_curve_for(loaded, store, c, results[c]));
    files.emplace_back("error_curve.csv", error_curve_csv(loaded.sweeps, labels, scs, curves));
  }
  if (markdown != nullptr) {  // what `run` prints (sim/present/table_view.h), else summary.md
    // csv and json keep stdout to the data: the lines under the table go to stderr.
    if (info.table != nullptr && info.table->machine() && !extras.empty())
      std::cerr << extras.substr(1);
    *markdown = info.table != nullptr ? stdout_table(*info.table, first.title, loaded.sweeps, rows,
                                                     n, table_md, extras)
                                      : md;
  }
  return files;
}

// Exports that a set may lack (dropped when the new set does not write them).
const std::vector<std::string> kStale{"trajectory.csv", "confusion.csv", "links.csv",
                                      "error_curve.csv"};
// Files derived from a campaign's results by `ncosim plot` and `ncosim report`: dropped when a set
// describes other results than the folder's (a new campaign, a merge, an export from elsewhere).
const std::vector<std::string> kDerived{"plot_*",    "trace.dat", "trace.gp",
                                        "trace.png", "trace.svg", "report.html"};

std::vector<std::string> stale_with_derived() {
  auto out = kStale;
  out.insert(out.end(), kDerived.begin(), kDerived.end());
  return out;
}

// Makes `to` the file `from`: a hard link (same filesystem: the folder's sibling), else a copy,
// synced before the set that holds it is swapped in.
void link_or_copy(const std::string& from, const std::filesystem::path& to) {
  if (::link(from.c_str(), to.c_str()) == 0) return;
  std::error_code ec;
  std::filesystem::copy_file(from, to, ec);
  if (ec)
    throw std::runtime_error(fmt::format("cannot put the run store '{}' into '{}': {}", from,
                                         to.string(), ec.message()));
  const int fd = ::open(to.c_str(), O_RDONLY | O_CLOEXEC);
  const bool synced = fd >= 0 && ::fsync(fd) == 0;
  if (fd >= 0) ::close(fd);
  if (!synced)
    throw std::runtime_error(
        fmt::format("cannot sync the copy '{}' of the run store", to.string()));
}

// Before a new store replaces an unfinished campaign's store beside the folder: says so.
void note_replaced_partial(const std::string& out, const std::string& partial) {
  std::error_code ec;
  if (!std::filesystem::exists(partial, ec)) return;
  std::string runs = "an unknown number of";
  try {
    runs = std::to_string(RunStore::open(partial, false).count_runs());
  } catch (const std::exception&) {
  }
  std::cerr << fmt::format(
      "ncosim: replacing the store of an unfinished campaign into '{}' ({}, {} run(s) "
      "committed; `run ... --resume` would have continued it)\n",
      out, partial, runs);
}

// Derives the exports of a store built beside the folder (`partial`), finishes it (checkpointed,
// one file), then swaps the exports and the store in as one set and removes the partial store's
// name. Until the swap the folder keeps its previous set, store included.
std::string export_and_install(const LoadedScenario& loaded, RunStore& store,
                               const std::string& out, const ExportInfo& info) {
  std::string md;
  auto files = derive_exports(loaded, store, info, &md);
  const std::string partial = store.path();
  store.close();
  write_output_set(out, files, stale_with_derived(),
                   {InstalledFile{"runs.sqlite", [&](const std::filesystem::path& to) {
                                    link_or_copy(partial, to);
                                  }}});
  remove_store_files(partial);
  return md;
}

// The largest run index + 1 that a store of this campaign may hold.
std::uint64_t run_limit(const LoadedScenario& loaded,
                        const std::map<std::string, std::string>& meta) {
  const TargetRule rule = target_of(meta, loaded);
  std::uint64_t limit = rule.on() ? rule.max_runs : 0;
  for (const auto& c : loaded.cases)
    limit = std::max(limit, static_cast<std::uint64_t>(c.scenario->run.runs));
  return limit;
}

// A partial store that is the very file of the set's runs.sqlite was left by a kill after the
// swap and before its name was removed: the campaign it holds is finished, so the name goes.
void settle_partial(const std::string& out) {
  const std::string partial = partial_store_path(out), live = store_path(out);
  std::error_code ec;
  if (std::filesystem::exists(partial, ec) && std::filesystem::exists(live, ec) &&
      std::filesystem::equivalent(partial, live, ec)) {
    remove_store_files(partial);
  }
}

}  // namespace

Shard parse_shard(const std::string& text) {
  const auto bad = [&] {
    return ScenarioError(
        fmt::format("--shard: expected I/N with 1 <= I <= N (e.g. 2/4), got '{}'", text));
  };
  const auto slash = text.find('/');
  if (slash == std::string::npos) throw bad();
  std::uint64_t i = 0, n = 0;
  const char* b = text.data();
  const char* e = text.data() + text.size();
  auto r1 = std::from_chars(b, b + slash, i);
  auto r2 = std::from_chars(b + slash + 1, e, n);
  if (r1.ec != std::errc() || r1.ptr != b + slash || r2.ec != std::errc() || r2.ptr != e || i < 1 ||
      n < 1 || i > n || n > 1'000'000) {
    throw bad();
  }
  return Shard{i - 1, n};
}

namespace {

// --target-ci, --max-runs and --replace checked before the scenario is read.
void check_target_options(const RunCommand& cmd) {
  if (cmd.replace && cmd.resume) {
    throw ScenarioError(
        "--replace: not with --resume (--resume continues the stored campaign, --replace discards "
        "it)");
  }
  if (!cmd.target_ci && cmd.max_runs > 0) throw ScenarioError("--max-runs: only with --target-ci");
  if (cmd.target_ci &&
      (!std::isfinite(*cmd.target_ci) || *cmd.target_ci <= 0.0 || *cmd.target_ci >= 1.0)) {
    throw ScenarioError(
        fmt::format("--target-ci: expected a relative half-width in (0, 1), e.g. 0.01, got {}",
                    *cmd.target_ci));
  }
  if (cmd.target_ci && cmd.max_runs <= 0) {
    throw ScenarioError(
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
      throw ScenarioError(
          "--target-ci: every sweep case must have the same run.runs (the batch size)");
    }
  }
  if (cmd.max_runs < batch) {
    throw ScenarioError(fmt::format(
        "--max-runs: expected at least run.runs = {} (one batch), got {}", batch, cmd.max_runs));
  }
  bool reachable = false;
  for (const auto& c : loaded.cases) {
    for (const auto& e : c.scenario->estimators)
      reachable = reachable || e.design->report().status == "ok";
  }
  if (!reachable)
    throw ScenarioError(
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
  throw ScenarioError(
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
      throw ScenarioError(
          fmt::format("--resume: {} holds a different campaign: {} differ(s) (stored vs now); run "
                      "without --resume to start afresh, or choose another --out",
                      what, diff));
    }
  };
  bool copied = false;  // a copy made here is removed again when it cannot be resumed
  try {
    if (!fs::exists(partial, ec)) {
      if (!fs::exists(live, ec)) {
        throw ScenarioError(
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
    throw ScenarioError(fmt::format("--resume: {}", e.what()));
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
  double wall = 0.0;
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

// The closing line: "ncosim: 3 cases x 20 runs x 5000 periods = 60 runs in 8.7 s on 2 threads
// [x 3 MPI ranks][, shard I/N]; results in DIR/", with the runs stored before when resumed.
std::string closing_line(const RunCommand& cmd, const LoadedScenario& loaded,
                         const SessionTotals& t) {
  return fmt::format(
      "ncosim: {}{} in {} s on {} thread{}{}{}; results in {}/\n",
      campaign_size(loaded, t.case_runs),
      t.skipped > 0 ? fmt::format(" ({} stored before, {} simulated now)", t.skipped, t.simulated)
                    : "",
      t.wall >= 10.0 ? fmt::format("{:.1f}", t.wall) : fmt::format("{:.2f}", t.wall), t.threads,
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
      << closing_line(cmd, loaded, t);
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
  if (cmd.fail_on_status && !not_ok.empty()) {
    std::string list;
    for (const auto& r : not_ok) list += "  " + r + "\n";
    std::cerr << fmt::format(
        "ncosim: --fail-on-status: {} row(s) with an unexpected status (results written to "
        "{}/):\n{}",
        not_ok.size(), cmd.out, list);
    return kExitFlagged;
  }
  return 0;
}

// Under mpirun, the MPI session (null otherwise); throws when this build has no MPI.
std::unique_ptr<MpiSession> start_mpi() {
  if (!mpi_launched()) return nullptr;
  if (!mpi_available()) {
    throw ScenarioError(
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
  CampaignResult res = session.mpi ? session.mpi->run(sc, c, opt) : run_campaign(sc, opt);
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
    simulate_run(*loaded.cases.front().scenario, 0, &session.trace);
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
  const Shard shard = cmd.shard.empty() ? Shard{} : parse_shard(cmd.shard);
  check_target_options(cmd);
  LoadedScenario loaded = load_cases(cmd.file, cmd.sets, cmd.overrides);
  reference_case_index(loaded);  // [paired] reference_case: bad input before t = 0
  const std::string& out = cmd.out;
  auto meta =
      campaign_meta(loaded, cmd.overrides,
                    cmd.shard.empty() ? "" : fmt::format("{}/{}", shard.index + 1, shard.count));
  const TargetRule rule = target_rule(cmd, loaded, meta);
  const TableRequest table{cmd.columns,
                           cmd.format};  // sim/present/table_view.h: bad --columns before t = 0
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
  session.stored = register_cases(store, loaded, cmd.resume);

  // One progress line for the whole campaign: redrawn on a terminal, a line every 5 s in a log.
  CampaignProgress progress(cmd.quiet     ? CampaignProgress::Mode::off
                            : ::isatty(2) ? CampaignProgress::Mode::terminal
                                          : CampaignProgress::Mode::log);
  set_progress_total(session, progress);
  session.progress = &progress;
  progress.start();
  StopSignals signals;
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

int cmd_export(const std::string& dir, const std::string& out, const std::string& command_line) {
  const std::string path = store_path(dir);
  const std::string target = out.empty() ? dir : out;
  // One writer per folder, for the whole command: a set swapped in by another process between
  // reading the store and writing the exports would otherwise pair its store with these exports.
  const OutputFolderLock folder_lock(target);
  RunStore store;
  LoadedScenario loaded;
  std::map<std::string, std::string> meta;
  try {
    store = RunStore::open(path, false);  // reading never writes the store
    meta = store.meta();
    loaded = reload(meta, path);
    store.verify(loaded.cases.size(), run_limit(loaded, meta));
  } catch (const StoreError& e) {
    throw ScenarioError(fmt::format("export: {}", e.what()));
  }
  bool same_folder = false;
  {
    std::error_code ec;
    same_folder =
        output_set_folder(dir) == output_set_folder(target) ||
        (std::filesystem::exists(target, ec) && std::filesystem::equivalent(dir, target, ec));
  }
  ExportInfo info;
  info.command_line = command_line;
  info.stopped = meta.count("stopped") != 0 ? meta.at("stopped") : "";
  std::vector<std::pair<std::string, std::string>> files;
  try {
    files = derive_exports(loaded, store, info, nullptr);
  } catch (const StoreError& e) {
    throw ScenarioError(fmt::format("export: {}", e.what()));
  }
  if (same_folder) {
    // The set's own store is carried over as it is; figures derived from it stay valid.
    write_output_set(target, files, kStale);
  } else {
    // Another folder: its set becomes this store's, with a copy of it; what was derived from the
    // folder's previous results goes.
    write_output_set(target, files, stale_with_derived(),
                     {InstalledFile{"runs.sqlite", [&](const std::filesystem::path& to) {
                                      store.copy_to(to.string());
                                    }}});
  }
  store.close();
  std::cout << fmt::format("exports of {} written to {}/\n", path, target);
  return 0;
}

namespace {

// The run stores of a campaign's shards, opened read-only, with their campaign tables.
struct ShardStores {
  std::vector<RunStore> stores;
  std::vector<std::map<std::string, std::string>> metas;
};

// Opens the store of each folder; throws when the output folder is one of them, when one does
// not open or when they are shards of different campaigns.
ShardStores open_shards(const std::string& out, const std::vector<std::string>& dirs) {
  namespace fs = std::filesystem;
  std::error_code ec;
  for (const auto& d : dirs) {
    if (fs::exists(out, ec) && fs::exists(d, ec) && fs::equivalent(out, d, ec)) {
      throw ScenarioError(fmt::format("merge: the output folder '{}' is also an input", out));
    }
  }
  ShardStores s;
  for (const auto& d : dirs) {
    try {
      s.stores.push_back(RunStore::open(store_path(d), false));
      s.metas.push_back(s.stores.back().meta());
      check_campaign_meta(s.metas.back(), store_path(d));
    } catch (const StoreError& e) {
      throw ScenarioError(fmt::format("merge: {}", e.what()));
    }
    const std::string diff = identity_difference(s.metas.front(), s.metas.back(), false);
    if (!diff.empty()) {
      throw ScenarioError(
          fmt::format("merge: {} and {} are shards of different campaigns: {} differ(s)",
                      store_path(dirs.front()), store_path(d), diff));
    }
  }
  return s;
}

// The shard holding each (case, run); throws when two shards hold the same one.
std::map<std::pair<std::size_t, std::uint64_t>, std::size_t> run_owners(
    ShardStores& shards, const std::vector<std::string>& dirs, const LoadedScenario& loaded) {
  std::map<std::pair<std::size_t, std::uint64_t>, std::size_t> owner;
  for (std::size_t s = 0; s < shards.stores.size(); ++s) {
    for (std::size_t c = 0; c < loaded.cases.size(); ++c) {
      for (std::uint64_t r : shards.stores[s].done_runs(c)) {
        const auto [it, fresh] = owner.emplace(std::make_pair(c, r), s);
        if (!fresh) {
          throw ScenarioError(
              fmt::format("merge: run {} of case {} is in both {} and {} (overlapping shards)", r,
                          c + 1, store_path(dirs[it->second]), store_path(dirs[s])));
        }
      }
    }
  }
  return owner;
}

// Throws naming the first missing runs unless every run of every case has an owner (with
// --target-ci, every run up to --max-runs: the shards run to it and the merge decides).
void check_complete(const std::map<std::pair<std::size_t, std::uint64_t>, std::size_t>& owner,
                    const LoadedScenario& loaded, const TargetRule& rule) {
  std::vector<std::string> missing;
  std::size_t missing_count = 0;
  for (std::size_t c = 0; c < loaded.cases.size(); ++c) {
    const auto runs =
        rule.on() ? rule.max_runs : static_cast<std::uint64_t>(loaded.cases[c].scenario->run.runs);
    for (std::uint64_t r = 0; r < runs; ++r) {
      if (owner.count({c, r}) != 0) continue;
      ++missing_count;
      if (missing.size() < 5)
        missing.push_back(loaded.cases.size() > 1 ? fmt::format("case {} run {}", c + 1, r)
                                                  : fmt::format("run {}", r));
    }
  }
  if (missing_count > 0) {
    std::string list;
    for (std::size_t i = 0; i < missing.size(); ++i) list += (i ? ", " : "") + missing[i];
    throw ScenarioError(fmt::format(
        "merge: {} run(s) missing from the given stores (first: {}); merge every shard, "
        "each complete (`ncosim run ... --shard I/N --resume` finishes one)",
        missing_count, list));
  }
}

// The campaign table of the merged store: the first shard's, unsharded, with the shards' wall
// time summed and the folders it was merged from.
std::map<std::string, std::string> merged_meta(
    const std::vector<std::map<std::string, std::string>>& metas,
    const std::vector<std::string>& dirs) {
  auto meta = metas.front();
  meta["shard"] = "";
  meta.erase("store");
  double wall = 0.0;
  for (const auto& m : metas) {
    try {
      wall += std::stod(m.at("wall_seconds"));
    } catch (...) {
    }
  }
  meta["wall_seconds"] = fmt::format("{:.17g}", wall);
  meta["merged_from"] = json_text(dirs);
  meta["stopped"] = "";
  return meta;
}

// Case c of every shard into the merged store: estimator names, runs with their link
// counters, and the timing of the first shard that measured it.
void merge_case(ShardStores& shards, RunStore& merged, const Scenario& sc, std::size_t c) {
  std::vector<std::string> names;
  for (const auto& e : sc.estimators) names.push_back(e.name);
  merged.put_estimators(c, names);
  std::vector<StoredRun> batch;
  for (auto& store : shards.stores) {
    std::map<std::uint64_t, RunLinks> links;
    for (auto& [run, l] : store.load_case_links(c)) links.emplace(run, std::move(l));
    for (auto& [run, m] : store.load_case(c)) {
      StoredRun sr{c, run, std::move(m), std::nullopt};
      if (auto it = links.find(run); it != links.end()) sr.links = std::move(it->second);
      batch.push_back(std::move(sr));
    }
  }
  merged.put_runs(batch);
  for (auto& store : shards.stores) merged.add_curve(c, store.curve(c));
  std::vector<double> ns(sc.estimators.size(), std::nan(""));
  for (auto& store : shards.stores) {
    const auto t = store.timing(c, sc.estimators.size());
    bool any = false;
    for (double v : t) any = any || std::isfinite(v);
    if (any) {
      ns = t;
      break;
    }
  }
  merged.put_timing(c, ns);
}

}  // namespace

int cmd_merge(const std::string& out, const std::vector<std::string>& dirs,
              const std::string& command_line) {
  if (dirs.empty()) throw ScenarioError("merge: expected at least one shard folder");
  ShardStores shards = open_shards(out, dirs);
  LoadedScenario loaded;
  try {
    loaded = reload(shards.metas.front(), store_path(dirs.front()));
    for (std::size_t i = 0; i < shards.stores.size(); ++i) {
      shards.stores[i].verify(loaded.cases.size(), run_limit(loaded, shards.metas[i]));
    }
  } catch (const StoreError& e) {
    throw ScenarioError(fmt::format("merge: {}", e.what()));
  }
  // Every (case, run) exactly once.
  const auto owner = run_owners(shards, dirs, loaded);
  check_complete(owner, loaded, target_of(shards.metas.front(), loaded));
  const OutputFolderLock folder_lock(out);  // sim/files/output_set.h
  prepare_output_dir(out);
  // Built beside the folder and swapped in with the exports (export_and_install).
  note_replaced_partial(out, partial_store_path(out));
  RunStore merged = RunStore::create(partial_store_path(out), merged_meta(shards.metas, dirs));
  try {
    for (std::size_t c = 0; c < loaded.cases.size(); ++c)
      merge_case(shards, merged, *loaded.cases[c].scenario, c);
    for (auto& store : shards.stores) {
      for (const auto& [name, content] : store.artifacts()) merged.put_artifact(name, content);
    }
  } catch (...) {  // a write failure (the shards were verified before): no partial store stays
    const std::string partial = merged.path();
    merged = RunStore();
    remove_store_files(partial);
    throw;
  }
  for (auto& store : shards.stores) store.close();
  ExportInfo info;
  info.command_line = command_line;
  export_and_install(loaded, merged, out, info);
  std::cout << fmt::format("{} store(s) merged: {} runs x {} case(s); results in {}/\n",
                           dirs.size(), owner.size(), loaded.cases.size(), out);
  return 0;
}

}  // namespace ncosim::sim
