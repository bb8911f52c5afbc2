// sim/cmd/campaign_meta.cc — see sim/cmd/campaign_meta.h.
#include "sim/cmd/campaign_meta.h"

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

std::string json_text(const nlohmann::json& j) { return j.dump(); }

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

namespace {

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

}  // namespace

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

namespace {

// The typed fields of a stored campaign table, each checked with one StoreError naming the store,
// the field, what it must hold and what it holds.
class MetaChecker {
 public:
  MetaChecker(const std::map<std::string, std::string>& meta, const std::string& path)
      : meta_(meta), path_(path) {}

  StoreError bad(const std::string& key, const std::string& expected) const {
    const auto it = meta_.find(key);
    std::string got = it == meta_.end()
                          ? std::string("nothing (the field is missing)")
                          : fmt::format("'{}'", config::escape_text(it->second.substr(0, 60)));
    if (it != meta_.end() && it->second.size() > 60) got += "...";
    return StoreError(fmt::format(
        "run store '{}': campaign field '{}': expected {}, got {} (the store is damaged or "
        "was edited; re-run the campaign)",
        path_, key, expected, got));
  }
  const std::string& text(const std::string& key) const {
    const auto it = meta_.find(key);
    if (it == meta_.end()) throw bad(key, "a value");
    return it->second;
  }
  void whole(const std::string& key, std::uint64_t min, bool optional) const {
    const auto it = meta_.find(key);
    if (it == meta_.end() || it->second.empty()) {
      if (optional) return;
      throw bad(key, fmt::format("a whole number >= {}", min));
    }
    std::uint64_t v = 0;
    const auto& t = it->second;
    const auto r = std::from_chars(t.data(), t.data() + t.size(), v);
    if (r.ec != std::errc() || r.ptr != t.data() + t.size() || v < min) {
      throw bad(key, fmt::format("{}a whole number >= {}", optional ? "empty or " : "", min));
    }
  }
  template <class Ok>
  void json_of(const std::string& key, bool optional, Ok&& ok, const char* expected) const {
    const auto it = meta_.find(key);
    if (it == meta_.end()) {
      if (optional) return;
      throw bad(key, expected);
    }
    if (optional && it->second.empty()) return;
    const auto j = nlohmann::json::parse(it->second, nullptr, false);
    if (j.is_discarded() || !ok(j)) throw bad(key, expected);
  }
  void number(const std::string& key, bool optional, double lo, double hi,
              const char* expected) const {
    const auto it = meta_.find(key);
    if (it == meta_.end() || it->second.empty()) {
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
  }

 private:
  const std::map<std::string, std::string>& meta_;
  const std::string& path_;
};

bool json_strings(const nlohmann::json& j) {
  if (!j.is_array()) return false;
  return std::all_of(j.begin(), j.end(), [](const nlohmann::json& e) { return e.is_string(); });
}

bool json_string_map(const nlohmann::json& j) {
  if (!j.is_object()) return false;
  return std::all_of(j.begin(), j.end(), [](const nlohmann::json& v) { return v.is_string(); });
}

}  // namespace

void check_campaign_meta(const std::map<std::string, std::string>& meta, const std::string& path) {
  const MetaChecker m(meta, path);
  for (const char* key :
       {"scenario_file", "scenario_path", "scenario_text", "ncosim_version", "git_commit"}) {
    (void)m.text(key);
  }
  const std::string& hash = m.text("scenario_hash");
  if (hash.size() != 16 || hash.find_first_not_of("0123456789abcdef") != std::string::npos) {
    throw m.bad("scenario_hash", "16 hexadecimal digits");
  }
  m.whole("seed", 0, false);
  m.whole("runs", 1, false);
  m.whole("periods", 1, false);
  m.whole("cases", 1, false);
  m.whole("override_runs", 1, true);
  m.whole("override_periods", 1, true);
  m.whole("override_seed", 0, true);
  m.whole("max_runs", 1, true);
  for (const char* key : {"threads", "ranks"}) {  // absent in stores of older versions, never empty
    if (meta.count(key) != 0) m.whole(key, 1, false);
  }
  m.json_of("overrides", false, json_strings, "a JSON array of strings (the --set overrides)");
  m.json_of("merged_from", true, json_strings, "a JSON array of folder names");
  m.json_of("inputs", true, json_string_map, "a JSON object of input file -> content hash");
  m.number("wall_seconds", true, 0.0, std::numeric_limits<double>::max(),
           "a finite number of seconds >= 0");
  m.number("target_ci", true, std::numeric_limits<double>::min(), 1.0 - 1e-16,
           "empty or a number in (0, 1)");
  if (const auto it = meta.find("shard"); it != meta.end() && !it->second.empty()) {
    try {
      (void)parse_shard(it->second);
    } catch (const config::ScenarioError&) {
      throw m.bad("shard", "empty or I/N with 1 <= I <= N");
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

LoadedScenario reload(const std::map<std::string, std::string>& meta, const std::string& path) {
  check_campaign_meta(meta, path);
  const auto sets = nlohmann::json::parse(meta.at("overrides")).get<std::vector<std::string>>();
  LoadedScenario loaded;
  try {
    loaded = load_cases_text(meta.at("scenario_path"), meta.at("scenario_text"), sets,
                             overrides_of(meta));
  } catch (const config::ScenarioError& e) {
    // The text is the store's, not the file's on disk (which may have changed since).
    throw config::ScenarioError(
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
      throw config::ScenarioError(
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

namespace {

// Fewer runs than this never stop a campaign: a CI from a handful of runs is itself too noisy.
constexpr std::uint64_t kTargetMinRuns = 20;

}  // namespace

TargetRule target_of(const std::map<std::string, std::string>& meta, const LoadedScenario& loaded) {
  TargetRule t;
  const auto it = meta.find("target_ci");
  if (it == meta.end() || it->second.empty()) return t;
  t.rel = std::stod(it->second);
  t.max_runs = std::stoull(meta.at("max_runs"));
  t.batch = static_cast<std::uint64_t>(loaded.cases.front().scenario->run.runs);
  return t;
}

namespace {

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

}  // namespace

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

Shard parse_shard(const std::string& text) {
  const auto bad = [&] {
    return config::ScenarioError(
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

}  // namespace ncosim::sim
