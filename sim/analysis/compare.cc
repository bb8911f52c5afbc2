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
#include "sim/analysis/output.h"
#include "sim/analysis/paired.h"
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

// Scales both rows' values by 2^-e, the largest |value| scaled into [0.5, 1), and returns e:
// sums, squares and variances of values up to the largest double cannot overflow, and a power of
// two changes no digit (the p-values and the relative change do not depend on the scale).
int scale_values(RunValues& vb, RunValues& vn) {
  double largest = 0.0;
  for (const auto* m : {&vb, &vn}) {
    for (const auto& [run, v] : *m) largest = std::max(largest, std::abs(v));
  }
  int e = 0;
  std::frexp(largest, &e);
  for (auto* m : {&vb, &vn}) {
    for (auto& [run, v] : *m) v = std::ldexp(v, -e);
  }
  return e;
}

// The difference of the scaled values: paired on the runs both have when the case's seeds agree
// and at least two pair, else Welch's unpaired test. Sets out.test, out.pairs and the note; a and
// c get the values tested. False when there are fewer than 2 runs to test.
bool difference_of(const RunValues& vb, const RunValues& vn, bool same_seed,
                   const CompareOptions& o, std::vector<double>& a, std::vector<double>& c,
                   std::optional<Difference>& d, CompareRow& out) {
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
  const double level = 1.0 - o.alpha;
  if (a.size() >= 2) {
    d = paired_difference(a, c, level);
    out.test = "paired";
    out.pairs = a.size();
    if (a.size() < vb.size() || a.size() < vn.size()) {
      out.note = fmt::format("paired on the {} runs both have", a.size());
    }
    return true;
  }
  a.clear();
  c.clear();
  for (const auto& [run, v] : vb) a.push_back(v);
  for (const auto& [run, v] : vn) c.push_back(v);
  if (a.size() < 2 || c.size() < 2) {
    out.note = "fewer than 2 runs";
    return false;
  }
  d = welch_difference(a, c, level);
  out.test = "welch";
  out.note = same_seed ? "no common runs" : "different seeds: unpaired";
  return true;
}

// The difference back in the metric's unit (2^e times the scaled one); what exceeds a double
// there (a difference or CI beyond 1.8e308, a relative change of new / base > 1.8e308) is left
// empty and said in the note.
void set_difference(const Difference& d, int e, CompareRow& out) {
  const auto unscaled = [e](double v) { return std::ldexp(v, e); };
  std::vector<std::string> beyond;
  out.base_mean = unscaled(d.base_mean);
  out.new_mean = unscaled(d.new_mean);
  const double diff = unscaled(d.diff);
  if (std::isfinite(diff)) out.diff = diff;
  if (d.diff_half) {
    const double low = unscaled(d.diff - *d.diff_half), high = unscaled(d.diff + *d.diff_half);
    if (std::isfinite(low) && std::isfinite(high)) {
      out.diff_low = low;
      out.diff_high = high;
    }
  }
  if (!out.diff || (d.diff_half && !out.diff_low)) beyond.emplace_back("difference");
  if (d.ratio) {
    if (std::isfinite(*d.ratio - 1.0)) out.relative = *d.ratio - 1.0;
    if (out.relative && d.ratio_half && std::isfinite(*out.relative - *d.ratio_half) &&
        std::isfinite(*out.relative + *d.ratio_half)) {
      out.relative_low = *out.relative - *d.ratio_half;
      out.relative_high = *out.relative + *d.ratio_half;
    }
    if (!out.relative || (d.ratio_half && !out.relative_low))
      beyond.emplace_back("relative change");
  }
  if (!beyond.empty()) {
    out.note += fmt::format("{}{} or its CI beyond the range of a double",
                            out.note.empty() ? "" : "; ", fmt::join(beyond, " and "));
  }
}

// Tests one matched row: divergence first, then the difference of the metric's means (paired or
// Welch) with its one-sided p-values against the tolerance.
void test_row(const RunFolder& bf, const RunFolder::Row& b, const RunFolder& nf,
              const RunFolder::Row& n, const CompareOptions& o, CompareRow& out) {
  out.runs_base = b.run.size();
  out.runs_new = n.run.size();
  if (judge_divergence(b, nf, n, out)) return;
  auto vb = finite_values(b), vn = finite_values(n);
  if (vb.empty() && vn.empty()) {
    out.note = fmt::format("no {} values", o.metric);
    return;
  }
  if (vb.empty() || vn.empty()) {
    out.note = fmt::format("{} only in {}", o.metric, vb.empty() ? "NEW" : "BASE");
    return;
  }
  const int e = scale_values(vb, vn);
  std::vector<double> a, c;
  std::optional<Difference> d;
  if (!difference_of(vb, vn, case_seed(bf, b) == case_seed(nf, n), o, a, c, d, out)) return;
  if (!d) {
    out.test = "none";
    out.note = "no interval";
    return;
  }
  const RelativeTest t = relative_test(a, c, out.test == "paired", o.tolerance);
  if (!std::isfinite(t.p_worse) || !std::isfinite(t.p_better)) {
    // Not reached on finite input after the scaling; never let it pass for "unchanged".
    throw CompareInputError(fmt::format("{}: {}: the test of {} is not finite (p = {}, {})",
                                        (fs::path(nf.dir) / "runs.csv").string(),
                                        row_text(nf.sweep_keys, n), o.metric, t.p_worse,
                                        t.p_better));
  }
  out.p_worse = t.p_worse;
  out.p_better = t.p_better;
  set_difference(*d, e, out);
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
                CompareResult& res) {
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
    } else {
      used[it->second] = true;
      test_row(base, b, fresh, fresh.rows[it->second], options, row);
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
  }
}

// The tested rows' verdicts from their p-values, Holm-adjusted over every tested row for each
// direction when asked; then the count of each verdict.
void judge_rows(const CompareOptions& options, CompareResult& res) {
  std::vector<std::size_t> tested;
  std::vector<double> pw, pb;
  for (std::size_t i = 0; i < res.rows.size(); ++i) {
    if (res.rows[i].p_worse) {
      tested.push_back(i);
      pw.push_back(*res.rows[i].p_worse);
      pb.push_back(*res.rows[i].p_better);
    }
  }
  res.tested = tested.size();
  if (options.holm) {
    pw = holm_adjust(pw);
    pb = holm_adjust(pb);
  }
  for (std::size_t j = 0; j < tested.size(); ++j) {
    CompareRow& r = res.rows[tested[j]];
    r.p_worse = pw[j];
    r.p_better = pb[j];
    r.verdict = pw[j] <= options.alpha ? "worse" : pb[j] <= options.alpha ? "better" : "unchanged";
  }
  for (const auto& r : res.rows) {
    if (r.verdict == "worse")
      ++res.worse;
    else if (r.verdict == "better")
      ++res.better;
    else if (r.verdict == "unchanged")
      ++res.unchanged;
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
  match_rows(base, fresh, options, res);
  judge_rows(options, res);
  return res;
}

std::string compare_csv(const CompareResult& r) {
  std::string out;
  for (const auto& k : r.base.sweep_keys) out += csv_field(k) + ",";
  out +=
      "estimator,metric,verdict,test,runs_base,runs_new,pairs,base_mean,new_mean,diff,diff_ci_low,"
      "diff_ci_high,"
      "relative_change,relative_ci_low,relative_ci_high,p_worse,p_better,note\n";
  auto num = [](std::optional<double> v) {
    return v && std::isfinite(*v) ? fmt::format("{:.6g}", *v) : std::string();
  };
  for (const auto& row : r.rows) {
    for (const auto& l : row.labels) out += csv_field(l) + ",";
    out += fmt::format("{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}\n",
                       csv_field(row.estimator), csv_field(r.options.metric), row.verdict, row.test,
                       row.runs_base, row.runs_new, row.pairs, num(row.base_mean),
                       num(row.new_mean), num(row.diff), num(row.diff_low), num(row.diff_high),
                       num(row.relative), num(row.relative_low), num(row.relative_high),
                       num(row.p_worse), num(row.p_better), csv_field(row.note));
  }
  return out;
}

namespace {

// A Markdown table cell: '|' escaped.
std::string md_cell(const std::string& s) {
  std::string out;
  for (char ch : s) {
    if (ch == '|') out += '\\';
    out += ch;
  }
  return out;
}

// Which test the rows use and why: paired where run r of both folders drew the same random
// numbers (the same seed), Welch's unpaired test where they did not.
std::string pairing_text(const CompareResult& r) {
  const bool swept_seed = std::find(r.base.sweep_keys.begin(), r.base.sweep_keys.end(),
                                    "run.seed") != r.base.sweep_keys.end();
  const std::string paired =
      "paired on the runs both folders have (run r of both drew the same random numbers: common "
      "random numbers)";
  if (swept_seed) {
    return "test: per case, " + paired +
           " where the case's run.seed is the same in both, else Welch's unpaired test";
  }
  if (r.base.seed == r.fresh.seed)
    return fmt::format("test: {}; same seed {}", paired, r.base.seed);
  return fmt::format(
      "test: Welch's unpaired test: the seeds differ ({} -> {}), so run r is another realisation "
      "in "
      "each folder",
      r.base.seed, r.fresh.seed);
}

}  // namespace

std::string compare_markdown(const CompareResult& r) {
  const auto& o = r.options;
  std::string out = fmt::format("# ncosim compare: {}\n\n", o.metric);
  out += fmt::format("- BASE `{}`: {} (seed {}, scenario_hash {})\n", r.base.dir, r.base.scenario,
                     r.base.seed, r.base.scenario_hash);
  out += fmt::format("- NEW `{}`: {} (seed {}, scenario_hash {})\n", r.fresh.dir, r.fresh.scenario,
                     r.fresh.seed, r.fresh.scenario_hash);
  out += fmt::format(
      "- worse: mean {} significantly above (1 + {:g}) x BASE; one-sided tests at alpha = {:g}, {} "
      "over "
      "{} tested row(s); CI: two-sided {:g} %\n",
      o.metric, o.tolerance, o.alpha, o.holm ? "Holm-corrected" : "no correction", r.tested,
      100.0 * (1.0 - o.alpha));
  if (!r.differences.empty()) {
    out += "- BASE -> NEW differ in:\n";
    for (const auto& d : r.differences) out += fmt::format("  - {}\n", d);
  }
  out += fmt::format("- {}\n", pairing_text(r));
  for (const auto& w : r.warnings) out += fmt::format("- warning: {}\n", w);
  out += "\n|";
  for (const auto& k : r.base.sweep_keys) out += fmt::format(" {} |", md_cell(k));
  out +=
      " estimator | verdict | test | runs | BASE | NEW | change % [CI] | p worse | p better | note "
      "|\n|";
  for (std::size_t i = 0; i < r.base.sweep_keys.size() + 10; ++i) out += "---|";
  out += "\n";
  auto g = [](std::optional<double> v, const char* f) {
    return v && std::isfinite(*v) ? fmt::format(fmt::runtime(f), *v) : std::string("–");
  };
  for (const auto& row : r.rows) {
    out += "|";
    for (const auto& l : row.labels) out += fmt::format(" {} |", md_cell(l));
    std::string change = "–";
    if (row.relative) {
      change = fmt::format("{:+.3f}", 100.0 * *row.relative);
      if (row.relative_low && row.relative_high) {
        change += fmt::format(" [{:+.3f}, {:+.3f}]", 100.0 * *row.relative_low,
                              100.0 * *row.relative_high);
      }
    }
    const std::string verdict = row.verdict == "worse" ? "**worse**" : row.verdict;
    out += fmt::format(" {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |\n",
                       md_cell(row.estimator), verdict, row.test,
                       row.test == "paired" ? std::to_string(row.pairs)
                                            : fmt::format("{} / {}", row.runs_base, row.runs_new),
                       g(row.base_mean, "{:.6g}"), g(row.new_mean, "{:.6g}"), change,
                       g(row.p_worse, "{:.3g}"), g(row.p_better, "{:.3g}"), md_cell(row.note));
  }
  out += fmt::format("\n{} worse, {} better, {} unchanged, {} not comparable: exit {}\n", r.worse,
                     r.better, r.unchanged, r.not_comparable, r.exit_code());
  return out;
}

int run_compare_command(const CompareCommand& c) {
  CompareOptions o = c.options;
  if (!(o.alpha > 0.0 && o.alpha < 1.0)) {
    throw CompareInputError(fmt::format("--alpha: expected a level in (0, 1), got {}", o.alpha));
  }
  if (!(o.tolerance >= 0.0 && o.tolerance < 1.0)) {
    throw CompareInputError(
        fmt::format("--tolerance: expected a relative tolerance in [0, 1), got {}", o.tolerance));
  }
  o.holm = c.correction == "holm";
  if (!c.out.empty()) prepare_output_dir(c.out);
  RunFolder base = read_run_folder(c.base, o.metric);
  RunFolder fresh = read_run_folder(c.fresh, o.metric);
  read_row_statuses(base);  // expected and unexpected status changes
  read_row_statuses(fresh);
  const CompareResult r = compare_folders(base, fresh, o);
  const std::string md = compare_markdown(r);
  if (!c.out.empty())
    write_files_atomically(c.out, {{"compare.csv", compare_csv(r)}, {"compare.md", md}});
  std::cout << md << std::flush;  // std::cout: what an embedding program captures (python/)
  return r.exit_code();
}

}  // namespace ncosim::sim
