// sim/analysis/compare.cc — `ncosim compare`: reading two output folders, matching and testing
// rows.
#include "sim/analysis/compare.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>

#include "sim/analysis/compare_manifest.h"
#include "sim/analysis/compare_stats.h"
#include "sim/analysis/output.h"
#include "sim/files/csv.h"

namespace ncosim::sim {

namespace fs = std::filesystem;

namespace {

// The seed of one case: a swept run.seed, else the manifest's.
std::uint64_t case_seed(const RunFolder& f, const RunFolder::Row& r) {
  for (std::size_t a = 0; a < f.sweep_keys.size(); ++a) {
    if (f.sweep_keys[a] == "run.seed") {
      try {
        return std::stoull(r.labels[a]);
      } catch (const std::exception&) {
        return f.seed;
      }
    }
  }
  return f.seed;
}

// The row's status from summary.csv (null when read_row_statuses found none).
const RunFolder::RowStatus* status_of(const RunFolder& f, const RunFolder::Row& r) {
  const auto i = static_cast<std::size_t>(&r - f.rows.data());
  return i < f.statuses.size() && !f.statuses[i].status.empty() ? &f.statuses[i] : nullptr;
}

// A status that differs between the folders, in the row's note: expected or not by NEW's row.
void note_status_change(const RunFolder& bf, const RunFolder::Row& b, const RunFolder& nf,
                        const RunFolder::Row& n, CompareRow& out) {
  const auto *sb = status_of(bf, b), *sn = status_of(nf, n);
  if (sb == nullptr || sn == nullptr || sb->status == sn->status) return;
  const bool expected =
      status_as_expected(sn->status, sn->expected_status);  // sim/scenario/scenario.h
  out.note += fmt::format("{}status {} -> {} ({})", out.note.empty() ? "" : "; ", sb->status,
                          sn->status, expected ? "expected" : "unexpected");
}

// A row that diverged in one folder or both: its verdict and note; false when neither diverged.
bool judge_divergence(const RunFolder::Row& b, const RunFolder& nf, const RunFolder::Row& n,
                      CompareRow& out) {
  const auto div_b = std::count(b.diverged.begin(), b.diverged.end(), true);
  const auto div_n = std::count(n.diverged.begin(), n.diverged.end(), true);
  if (div_n > 0 && div_b == 0) {
    // A row whose scenario expects it to diverge (the open-loop reference) is no regression.
    const auto* st = status_of(nf, n);
    const bool expected = st != nullptr && st->expected_status == "diverged";
    if (!expected) out.verdict = "worse";
    out.note = fmt::format("diverged in {} of {} NEW runs, none in BASE{}", div_n, n.run.size(),
                           expected ? " (expected_status = diverged)" : "");
    return true;
  }
  if (div_b > 0 && div_n == 0) {
    out.verdict = "better";
    out.note = fmt::format("diverged in {} of {} BASE runs, none in NEW", div_b, b.run.size());
    return true;
  }
  if (div_b > 0 && div_n > 0) {
    out.note = "diverged in both";
    return true;
  }
  return false;
}

using RunValues = std::vector<std::pair<std::int64_t, double>>;

// The row's finite (run, value) pairs in run order (runs are unique in a row: read_run_folder
// checks).
RunValues finite_values(const RunFolder::Row& r) {
  RunValues v;
  for (std::size_t i = 0; i < r.run.size(); ++i) {
    if (r.value[i] && std::isfinite(*r.value[i])) v.emplace_back(r.run[i], *r.value[i]);
  }
  std::sort(v.begin(), v.end());
  return v;
}

// The values to test: paired on the runs both have when the case's seeds agree and at least two
// pair (note when fewer than all), else every value of each side, unpaired (note why).
void values_to_test(const RunValues& vb, const RunValues& vn, bool same_seed,
                    std::vector<double>& a, std::vector<double>& c, bool& paired, CompareRow& out) {
  if (same_seed) {
    auto it = vn.begin();
    for (const auto& [run, v] : vb) {
      while (it != vn.end() && it->first < run) ++it;
      if (it == vn.end()) break;
      if (it->first != run) continue;
      a.push_back(v);
      c.push_back(it->second);
    }
  }
  paired = a.size() >= 2;
  if (paired) {
    if (a.size() < vb.size() || a.size() < vn.size())
      out.note = fmt::format("paired on the {} runs both have", a.size());
    return;
  }
  a.clear();
  c.clear();
  for (const auto& [run, v] : vb) a.push_back(v);
  for (const auto& [run, v] : vn) c.push_back(v);
  out.note = same_seed ? "fewer than 2 common runs: unpaired" : "different seeds: unpaired";
}

// Tests one matched row: divergence first, then the rank test of the per-run ratio (paired or
// not); the verdict waits for the family (judge_family).
std::optional<RowShift> test_row(const RunFolder& bf, const RunFolder::Row& b, const RunFolder& nf,
                                 const RunFolder::Row& n, const CompareOptions& o,
                                 CompareRow& out) {
  out.runs_base = b.run.size();
  out.runs_new = n.run.size();
  if (judge_divergence(b, nf, n, out)) return std::nullopt;
  const auto vb = finite_values(b), vn = finite_values(n);
  if (vb.empty() && vn.empty()) {
    out.note = fmt::format("no {} values", o.metric);
    return std::nullopt;
  }
  if (vb.empty() || vn.empty()) {
    out.note = fmt::format("{} only in {}", o.metric, vb.empty() ? "NEW" : "BASE");
    return std::nullopt;
  }
  std::vector<double> a, c;
  bool paired = false;
  values_to_test(vb, vn, case_seed(bf, b) == case_seed(nf, n), a, c, paired, out);
  return test_values(a, c, paired, out);
}

// The refusal's tail: each differing manifest field on its own line, and why a folder of an
// older ncosim cannot tell other runs or seeds from another scenario.
std::string what_differs(const RunFolder& base, const RunFolder& fresh,
                         const std::vector<std::string>& differences, bool scenario) {
  std::string out = "; what differs (BASE -> NEW):";
  for (const auto& d : differences) out += "\n  " + d;
  for (const auto* f : {&base, &fresh}) {
    if (!scenario || f->text_hash) continue;
    out += fmt::format(
        "\n  ({} {}: a manifest.json without scenario_text_hash (an older ncosim) and no run "
        "store; "
        "its scenario_hash also covers --runs, --periods and --seed, so other runs or seeds cannot "
        "be "
        "told from another scenario there: re-run it with this ncosim)",
        f == &base ? "BASE" : "NEW", f->dir);
  }
  return out;
}

// A folder's identity without its rows (the per-run values are read here, not kept).
RunFolder folder_identity(const RunFolder& f) {
  RunFolder id;
  id.dir = f.dir;
  id.scenario = f.scenario;
  id.title = f.title;
  id.scenario_hash = f.scenario_hash;
  id.seed = f.seed;
  id.partial = f.partial;
  id.sweep_keys = f.sweep_keys;
  return id;
}

// The input files whose content differs between the folders, as "'file' (BASE vs NEW), ...".
std::string input_differences(const RunFolder& base, const RunFolder& fresh) {
  std::string what;
  for (const auto& [file, h] : *base.inputs) {
    const auto it = fresh.inputs->find(file);
    if (it == fresh.inputs->end() || it->second != h) {
      what += fmt::format("{}'{}' ({} vs {})", what.empty() ? "" : ", ", file, h,
                          it == fresh.inputs->end() ? std::string("not read") : it->second);
    }
  }
  for (const auto& [file, h] : *fresh.inputs) {
    if (base.inputs->count(file) == 0)
      what += fmt::format("{}'{}' (not read vs {})", what.empty() ? "" : ", ", file, h);
  }
  return what;
}

// Refuses folders of different scenarios or input contents (warns instead with
// --allow-scenario-change), then warns of partial folders and refuses different sweep axes.
void check_comparable(const RunFolder& base, const RunFolder& fresh, const CompareOptions& options,
                      CompareResult& res) {
  const std::string base_man = (fs::path(base.dir) / "manifest.json").string();
  const std::string new_man = (fs::path(fresh.dir) / "manifest.json").string();
  if (!same_scenario_text(base, fresh)) {
    const std::string what =
        fmt::format("BASE {} (scenario_hash {}) and NEW {} (scenario_hash {})", base.scenario,
                    base.scenario_hash, fresh.scenario, fresh.scenario_hash);
    if (!options.allow_scenario_change) {
      throw CompareInputError(
          fmt::format("{}: a different scenario or different overrides than {}; pass "
                      "--allow-scenario-change to compare them anyway{}",
                      new_man, base_man, what_differs(base, fresh, res.differences, true)));
    }
    res.warnings.push_back(fmt::format("scenarios differ (--allow-scenario-change): {}", what));
  }
  if (base.inputs && fresh.inputs && *base.inputs != *fresh.inputs) {
    // The same scenario text can read input files whose content changed between the campaigns.
    const std::string what =
        "the content of the input file(s) " + input_differences(base, fresh) + " differs";
    if (!options.allow_scenario_change) {
      throw CompareInputError(
          fmt::format("{}: {} from {}; pass --allow-scenario-change to compare them anyway{}",
                      new_man, what, base_man, what_differs(base, fresh, res.differences, false)));
    }
    res.warnings.push_back(fmt::format("inputs differ (--allow-scenario-change): {}", what));
  }
  if (!base.partial.empty()) res.warnings.push_back(fmt::format("BASE holds {}", base.partial));
  if (!fresh.partial.empty()) res.warnings.push_back(fmt::format("NEW holds {}", fresh.partial));
  if (base.sweep_keys != fresh.sweep_keys) {
    throw CompareInputError(
        fmt::format("{}: sweep axes [{}] differ from {}'s [{}]",
                    (fs::path(fresh.dir) / "runs.csv").string(), fmt::join(fresh.sweep_keys, ", "),
                    (fs::path(base.dir) / "runs.csv").string(), fmt::join(base.sweep_keys, ", ")));
  }
}

// One result row per (labels, estimator): BASE's rows in order, each tested against NEW's row of
// the same key, then NEW's rows not in BASE. A row in one folder only is refused unless
// --allow-scenario-change.
void match_rows(const RunFolder& base, const RunFolder& fresh, const CompareOptions& options,
                CompareResult& res, std::vector<std::optional<RowShift>>& shifts) {
  const std::string base_runs = (fs::path(base.dir) / "runs.csv").string();
  const std::string new_runs = (fs::path(fresh.dir) / "runs.csv").string();
  std::map<std::pair<std::vector<std::string>, std::string>, std::size_t> in_new;
  for (std::size_t i = 0; i < fresh.rows.size(); ++i)
    in_new[{fresh.rows[i].labels, fresh.rows[i].estimator}] = i;
  std::vector<bool> used(fresh.rows.size(), false);
  for (const auto& b : base.rows) {
    CompareRow row;
    row.labels = b.labels;
    row.estimator = b.estimator;
    const auto it = in_new.find({b.labels, b.estimator});
    if (it == in_new.end()) {
      if (!options.allow_scenario_change) {
        throw CompareInputError(fmt::format("{}: missing row {} (present in {})", new_runs,
                                            row_text(base.sweep_keys, b), base_runs));
      }
      row.runs_base = b.run.size();
      row.note = "only in BASE";
      shifts.emplace_back();
    } else {
      used[it->second] = true;
      shifts.push_back(test_row(base, b, fresh, fresh.rows[it->second], options, row));
      note_status_change(base, b, fresh, fresh.rows[it->second], row);
    }
    res.rows.push_back(std::move(row));
  }
  for (std::size_t i = 0; i < fresh.rows.size(); ++i) {
    if (used[i]) continue;
    if (!options.allow_scenario_change) {
      throw CompareInputError(fmt::format("{}: missing row {} (present in {})", base_runs,
                                          row_text(fresh.sweep_keys, fresh.rows[i]), new_runs));
    }
    CompareRow row;
    row.labels = fresh.rows[i].labels;
    row.estimator = fresh.rows[i].estimator;
    row.runs_new = fresh.rows[i].run.size();
    row.note = "only in NEW";
    res.rows.push_back(std::move(row));
    shifts.emplace_back();
  }
}

// The verdicts of the tested rows (one family, sim/analysis/compare_stats.h), then the count of
// each verdict.
void judge_rows(const CompareOptions& options, const std::vector<std::optional<RowShift>>& shifts,
                CompareResult& res) {
  judge_family(res.rows, shifts, options);
  res.tested = static_cast<std::size_t>(
      std::count_if(shifts.begin(), shifts.end(), [](const auto& s) { return s.has_value(); }));
  for (const auto& r : res.rows) {
    if (r.verdict == "worse")
      ++res.worse;
    else if (r.verdict == "better")
      ++res.better;
    else if (r.verdict == "unchanged")
      ++res.unchanged;
    else if (r.verdict == "inconclusive")
      ++res.inconclusive;
    else
      ++res.not_comparable;
  }
}

}  // namespace

CompareResult compare_folders(const RunFolder& base, const RunFolder& fresh,
                              const CompareOptions& options) {
  CompareResult res;
  res.options = options;
  res.base = folder_identity(base);
  res.fresh = folder_identity(fresh);
  res.differences = manifest_differences(base, fresh);
  check_comparable(base, fresh, options, res);
  std::vector<std::optional<RowShift>> shifts;
  match_rows(base, fresh, options, res, shifts);
  judge_rows(options, shifts, res);
  return res;
}

int CompareResult::exit_code() const {
  if (worse > 0) return kCompareWorse;
  if (inconclusive > 0 && !options.allow_inconclusive) return kCompareInconclusive;
  return 0;
}

void check_compare_options(const CompareOptions& o) {
  if (!(o.alpha > 0.0 && o.alpha < 0.5)) {
    throw CompareInputError(fmt::format(
        "--alpha: expected a level in (0, 0.5) (the intervals are at 1 - 2 alpha), got {}",
        o.alpha));
  }
  if (!(o.tolerance >= 0.0 && o.tolerance < 1.0)) {
    throw CompareInputError(
        fmt::format("--tolerance: expected a relative tolerance in [0, 1), got {}", o.tolerance));
  }
  if (o.tolerance == 0.0 && !o.allow_inconclusive) {
    throw CompareInputError(
        "--tolerance: 0 leaves no row unchanged (an equivalence needs a band), so every row "
        "without a significant change would fail the gate: give a tolerance in (0, 1) (default "
        "0.05) or pass --allow-inconclusive");
  }
}

int run_compare_command(const CompareCommand& c) {
  CompareOptions o = c.options;
  o.holm = c.correction == "holm";
  check_compare_options(o);
  RunFolder base = read_run_folder(c.base, o.metric);
  RunFolder fresh = read_run_folder(c.fresh, o.metric);
  read_row_statuses(base);  // expected and unexpected status changes
  read_row_statuses(fresh);
  const CompareResult r = compare_folders(base, fresh, o);
  const std::string md = compare_markdown(r);
  if (!c.out.empty()) {
    // Created only now: bad input leaves no folder behind.
    prepare_output_dir(c.out);
    write_files_atomically(c.out, {{"compare.csv", compare_csv(r)}, {"compare.md", md}});
  }
  std::cout << md << std::flush;  // std::cout: what an embedding program captures (python/)
  return r.exit_code();
}

}  // namespace ncosim::sim
