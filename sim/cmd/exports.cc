// sim/cmd/exports.cc — see sim/cmd/exports.h.
#include "sim/cmd/exports.h"

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
#include "sim/cmd/campaign_meta.h"
#include "sim/cmd/manifest.h"
#include "sim/cmd/mpi_campaign.h"
#include "sim/files/output_set.h"
#include "sim/present/table_view.h"
#include "sim/run/campaign.h"
#include "sim/run/link_report.h"
#include "sim/run/overload.h"
#include "sim/run/progress.h"
#include "sim/scenario/resource_limits.h"
#include "sim/store/store.h"

namespace ncosim::sim {

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
    curve.merge(run_case(sc, 0, opt, nullptr).curve);
  }
  return curve;
}

namespace {

// What the exports of a store are made of: its campaign table, the runs they use, the rows.
struct ExportState {
  std::map<std::string, std::string> meta;
  Shard shard;
  TargetRule rule;
  std::vector<CampaignResult> results;  // per case
  LinkCoverage links;
  TargetDecision decision;
  std::vector<SummaryRow> rows;
  std::uint64_t done = 0, expected = 0;
  bool complete = false;
};

// The stored runs of every case with their link counters (links.csv needs them for every run the
// exports use: sim/run/link_report.h); with --target-ci decided, cut to the stopping point (runs
// beyond it, e.g. of shards, are not used).
void load_runs(const LoadedScenario& loaded, const RunStore& store, ExportState& s) {
  s.results.resize(loaded.cases.size());
  for (std::size_t c = 0; c < loaded.cases.size(); ++c) {
    CampaignResult& res = s.results[c];
    for (auto& [run, m] : store.load_case(c)) {
      res.run_ids.push_back(run);
      res.runs.push_back(std::move(m));
    }
  }
  s.links = load_link_runs(store, s.results);
  if (s.rule.on() && s.shard.count <= 1) {
    s.decision = decide_target(loaded, s.results, s.rule);
    if (s.decision.decided) {
      for (auto& res : s.results) {
        res.runs.resize(s.decision.runs);
        res.run_ids.resize(s.decision.runs);
        if (!res.link_runs.empty()) res.link_runs.resize(s.decision.runs);
      }
    }
  }
}

// The runs case `sc` is expected to hold: the decided count, --max-runs (this shard's part), or
// the runs the shard owns.
std::uint64_t expected_runs(const Scenario& sc, const ExportState& s) {
  if (s.decision.decided) return s.decision.runs;
  if (s.rule.on()) {
    return s.shard.count <= 1 ? s.rule.max_runs
                              : s.rule.max_runs / s.shard.count +
                                    (s.shard.index < s.rule.max_runs % s.shard.count ? 1 : 0);
  }
  return owned_runs(sc, s.shard);
}

// The summary rows of every case (with the stopping rule's reason and unmet targets), paired
// across cases; counts the runs done and expected.
void summarise_cases(const LoadedScenario& loaded, const RunStore& store, ExportState& s) {
  for (std::size_t c = 0; c < loaded.cases.size(); ++c) {
    const Scenario& sc = *loaded.cases[c].scenario;
    CampaignResult& res = s.results[c];
    res.ns_per_period = store.timing(c, sc.estimators.size());
    s.done += res.runs.size();
    s.expected += expected_runs(sc, s);
    auto case_rows = summarise(sc, res, loaded.cases[c].labels);
    for (std::size_t e = 0; e < case_rows.size(); ++e) {
      if (!s.decision.decided) continue;
      case_rows[e].stop = s.decision.reason;
      if (s.decision.met[c][e] == 0 && case_rows[e].status == "ok")
        case_rows[e].status = "ci_target_not_met";
    }
    s.rows.insert(s.rows.end(), case_rows.begin(), case_rows.end());
  }
  add_paired_across_cases(s.rows, loaded, reference_case_index(loaded));  // sim/analysis/paired.h
}

// The cases as the per-case reports take them: labels, scenarios, results.
struct CaseViews {
  std::vector<std::vector<std::string>> labels;
  std::vector<const Scenario*> scenarios;
  std::vector<const CampaignResult*> results;
};
CaseViews case_views(const LoadedScenario& loaded, const ExportState& s) {
  CaseViews v;
  for (std::size_t c = 0; c < loaded.cases.size(); ++c) {
    v.labels.push_back(loaded.cases[c].labels);
    v.scenarios.push_back(loaded.cases[c].scenario.get());
    v.results.push_back(&s.results[c]);
  }
  return v;
}

// "case, \"estimator\": status" of each row whose status is not as its scenario expects.
void report_not_ok(const LoadedScenario& loaded, const std::vector<SummaryRow>& rows,
                   std::vector<std::string>& not_ok) {
  for (const auto& r : rows) {
    if (status_as_expected(r.status, r.expected_status)) continue;  // [[estimator]] expected_status
    std::string where;
    for (std::size_t i = 0; i < r.sweep_labels.size(); ++i) {
      where += fmt::format("{} = {}, ", loaded.sweeps[i].key, r.sweep_labels[i]);
    }
    not_ok.push_back(fmt::format("{}\"{}\": {}", where, r.estimator, status_text(r)));
  }
}

// The lines under the summary table: consistency notes, why --target-ci stopped, and what a
// partial campaign or a shard holds.
std::string summary_extras(const LoadedScenario& loaded, const ExportState& s,
                           const ExportInfo& info) {
  std::string extras = consistency_notes(loaded.sweeps, s.rows);
  const CaseViews views = case_views(loaded, s);  // links and errors that grow: sim/run/overload.h
  extras += growth_notes(loaded.sweeps, views.labels, views.scenarios, views.results);
  const TargetRule& rule = s.rule;
  if (s.decision.decided) {
    extras += s.decision.reason == "target_ci"
                  ? fmt::format(
                        "\nStopped at {} runs per case: every row's 95 % CI half-width of mse is "
                        "within {:g} % of "
                        "its mean (`--target-ci {:g}`, batches of {}).\n",
                        s.decision.runs, 100.0 * rule.rel, rule.rel, rule.batch)
                  : fmt::format(
                        "\nStopped at `--max-runs {}`: the rows with status `ci_target_not_met` "
                        "did not reach "
                        "the 95 % CI half-width target of {:g} % of mse (`--target-ci {:g}`).\n",
                        s.decision.runs, 100.0 * rule.rel, rule.rel);
  }
  if (!s.complete || s.shard.count > 1) {
    extras += fmt::format(
        "\n**Partial results**: {} of {} runs{}{}.\n", s.done, s.expected,
        s.shard.count > 1 ? fmt::format(" of shard {}/{}", s.shard.index + 1, s.shard.count) : "",
        info.stopped.empty() ? "" : fmt::format(" (stopped by {})", info.stopped));
    if (!s.complete)
      extras += "`ncosim run FILE --out DIR --resume` (same options) runs the missing ones.\n";
    if (s.shard.count > 1)
      extras += "`ncosim merge OUT DIR...` combines the shards' stores into the whole campaign.\n";
  }
  return extras;
}

// manifest.json of the exports: the campaign's, with the store's inputs, ranks, progress,
// stopping rule and why links.csv is missing.
nlohmann::json export_manifest(const LoadedScenario& loaded, const ExportState& s,
                               const ExportInfo& info) {
  const auto& meta = s.meta;
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
  man["runs_done"] = s.done;
  man["runs_expected"] = s.expected;
  man["complete"] = s.complete;
  man["stopped"] = info.stopped.empty() ? nlohmann::json(nullptr) : nlohmann::json(info.stopped);
  man["shard"] = s.shard.count > 1 ? nlohmann::json(meta.at("shard")) : nlohmann::json(nullptr);
  const TargetDecision& decision = s.decision;
  if (s.rule.on()) {
    man["target_ci"] = {
        {"rel", s.rule.rel},
        {"max_runs", s.rule.max_runs},
        {"batch", s.rule.batch},
        {"runs", decision.decided ? nlohmann::json(decision.runs) : nlohmann::json(nullptr)},
        {"stop", decision.decided ? nlohmann::json(decision.reason) : nlohmann::json(nullptr)}};
  }
  if (!s.links.complete) {
    man["links_csv"] = fmt::format(
        "not written: {} of the {} stored runs have no link counters (a store written "
        "before ncosim counted them)",
        s.links.missing, s.links.missing + s.links.present);
  }
  return man;
}

// The exported files in their order: summary.csv and .md, runs.csv, transmissions.csv,
// design.json, manifest.json, and, where there is content, links.csv, trajectory.csv,
// confusion.csv and error_curve.csv.
std::vector<std::pair<std::string, std::string>> export_files(const LoadedScenario& loaded,
                                                              const RunStore& store,
                                                              const ExportState& s,
                                                              const std::string& md,
                                                              const nlohmann::json& man) {
  const Scenario& first = *loaded.cases.front().scenario;
  const Eigen::Index n = first.model.plant.n();
  std::vector<std::vector<std::string>> labels;
  std::vector<const Scenario*> scs;
  std::vector<const CampaignResult*> res;
  for (std::size_t c = 0; c < loaded.cases.size(); ++c) {
    labels.push_back(loaded.cases[c].labels);
    scs.push_back(loaded.cases[c].scenario.get());
    res.push_back(&s.results[c]);
  }
  std::vector<std::pair<std::string, std::string>> files{
      {"summary.csv", summary_csv(loaded.sweeps, s.rows, n)},
      {"summary.md", md},
      {"runs.csv", runs_csv(loaded.sweeps, labels, scs, res)},
      {"transmissions.csv", transmissions_csv(loaded.sweeps, labels, scs, res)},
      {"design.json", design_json(loaded).dump(2) + "\n"},
      {"manifest.json", man.dump(2) + "\n"},
  };
  if (s.links.complete) files.emplace_back("links.csv", links_csv(loaded.sweeps, labels, scs, res));
  const auto art = store.artifacts();
  if (const auto it = art.find("trajectory.csv"); it != art.end())
    files.emplace_back("trajectory.csv", it->second);
  const std::string confusion = confusion_csv(loaded.sweeps, s.rows);
  if (confusion.find('\n') + 1 < confusion.size()) files.emplace_back("confusion.csv", confusion);
  if (first.run.error_curve) {
    std::vector<ErrorCurve> curves;
    for (std::size_t c = 0; c < loaded.cases.size(); ++c)
      curves.push_back(error_curve_for(loaded, store, c, s.results[c]));
    files.emplace_back("error_curve.csv", error_curve_csv(loaded.sweeps, labels, scs, curves));
  }
  return files;
}

}  // namespace

std::vector<std::pair<std::string, std::string>> derive_exports(const LoadedScenario& loaded,
                                                                const RunStore& store,
                                                                const ExportInfo& info,
                                                                std::string* markdown) {
  ExportState s;
  s.meta = store.meta();
  s.shard = shard_of(s.meta);
  s.rule = target_of(s.meta, loaded);
  load_runs(loaded, store, s);
  summarise_cases(loaded, store, s);
  if (info.not_ok != nullptr) {
    report_not_ok(loaded, s.rows, *info.not_ok);
    const CaseViews views = case_views(loaded, s);  // --fail-on-status fails on an overload too
    for (auto& line : overloaded_flows(loaded.sweeps, views.labels, views.scenarios, views.results))
      info.not_ok->push_back(std::move(line));
  }
  const Scenario& first = *loaded.cases.front().scenario;
  const Eigen::Index n = first.model.plant.n();
  s.complete = s.decision.decided || (!s.rule.on() && s.done == s.expected);
  if (info.complete != nullptr) *info.complete = s.complete;
  const std::string table_md = summary_markdown(first.title, loaded.sweeps, s.rows, n);
  const std::string extras = summary_extras(loaded, s, info);
  const std::string md = table_md + extras;
  auto files = export_files(loaded, store, s, md, export_manifest(loaded, s, info));
  if (markdown != nullptr) {  // what `run` prints (sim/present/table_view.h), else summary.md
    // csv and json keep stdout to the data: the lines under the table go to stderr.
    if (info.table != nullptr && info.table->machine() && !extras.empty())
      std::cerr << extras.substr(1);
    *markdown = info.table != nullptr ? stdout_table(*info.table, first.title, loaded.sweeps,
                                                     s.rows, n, table_md, extras)
                                      : md;
  }
  return files;
}

namespace {

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

}  // namespace

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

std::uint64_t run_limit(const LoadedScenario& loaded,
                        const std::map<std::string, std::string>& meta) {
  const TargetRule rule = target_of(meta, loaded);
  std::uint64_t limit = rule.on() ? rule.max_runs : 0;
  for (const auto& c : loaded.cases)
    limit = std::max(limit, static_cast<std::uint64_t>(c.scenario->run.runs));
  return limit;
}

void settle_partial(const std::string& out) {
  const std::string partial = partial_store_path(out), live = store_path(out);
  std::error_code ec;
  if (std::filesystem::exists(partial, ec) && std::filesystem::exists(live, ec) &&
      std::filesystem::equivalent(partial, live, ec)) {
    remove_store_files(partial);
  }
}

void check_folder_replace(const FolderWrite& w) {
  for (const bool partial : {false, true}) {
    if (partial && !w.with_partial) continue;
    const std::string path = partial ? partial_store_path(w.out) : store_path(w.out);
    std::error_code ec;
    if (!std::filesystem::exists(path, ec)) continue;
    std::int64_t runs = 0, lost = 0;
    std::string diff;
    try {
      const RunStore store = RunStore::open(path, false);
      runs = store.count_runs();
      if (runs == 0) continue;
      const auto stored = store.meta();
      check_campaign_meta(stored, path);
      diff = identity_difference(stored, *w.meta, true);
      for (std::size_t c = 0; diff.empty() && c < w.cases; ++c) {
        for (const std::uint64_t r : store.done_runs(c)) lost += w.holds(c, r) ? 0 : 1;
      }
    } catch (const StoreError&) {
      continue;  // damaged: nothing in it can be resumed or exported (replaced, as by `run`)
    }
    if (diff.empty() && lost == 0) continue;  // every run it holds comes back: nothing is lost
    const std::string what = !diff.empty()
                                 ? fmt::format("{} finished run(s) of a different campaign", runs)
                                 : fmt::format("{} run(s) that {} lack(s)", lost, w.source);
    if (w.replace) {
      std::cerr << fmt::format("ncosim: --replace: replacing {} in {}\n", what, path);
      continue;
    }
    throw config::ScenarioError(fmt::format(
        "{}: '{}' holds {} ({}{}){}; `--replace` replaces them, or choose another output folder",
        w.command, w.out, what, path, partial ? ", the store of an unfinished campaign" : "",
        diff.empty() ? "" : fmt::format(": {} differ(s) (stored vs {})", diff, w.source)));
  }
}

int cmd_export(const std::string& dir, const std::string& out, bool replace,
               const std::string& command_line) {
  const std::string path = store_path(dir);
  const std::string target = out.empty() ? dir : out;
  // One writer per folder, for the whole command: a set swapped in by another process between
  // reading the store and writing the exports would otherwise pair its store with these exports.
  const OutputFolderLock folder_lock(target);  // restores a set an interrupted write moved aside
  if (!out.empty()) restore_interrupted_write(dir);  // the source's too
  RunStore store;
  LoadedScenario loaded;
  std::map<std::string, std::string> meta;
  try {
    store = RunStore::open(path, false);  // reading never writes the store
    meta = store.meta();
    loaded = reload(meta, path);
    store.verify(loaded.cases.size(), run_limit(loaded, meta));
  } catch (const StoreError& e) {
    throw config::ScenarioError(fmt::format("export: {}", e.what()));
  }
  bool same_folder = false;
  {
    std::error_code ec;
    same_folder =
        output_set_folder(dir) == output_set_folder(target) ||
        (std::filesystem::exists(target, ec) && std::filesystem::equivalent(dir, target, ec));
  }
  if (!same_folder) {  // the rule of `run --out`: never lose another folder's runs silently
    std::vector<std::vector<std::uint64_t>> done;
    for (std::size_t c = 0; c < loaded.cases.size(); ++c) done.push_back(store.done_runs(c));
    check_folder_replace(FolderWrite{
        "export", target, &meta, fmt::format("the store of '{}'", dir), loaded.cases.size(),
        [&](std::size_t c, std::uint64_t r) {
          return c < done.size() && std::binary_search(done[c].begin(), done[c].end(), r);
        },
        replace, false});
  }
  ExportInfo info;
  info.command_line = command_line;
  info.stopped = meta.count("stopped") != 0 ? meta.at("stopped") : "";
  std::vector<std::pair<std::string, std::string>> files;
  try {
    files = derive_exports(loaded, store, info, nullptr);
  } catch (const StoreError& e) {
    throw config::ScenarioError(fmt::format("export: {}", e.what()));
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

}  // namespace ncosim::sim
