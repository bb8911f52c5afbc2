// sim/analysis/compare_format.cc — compare.csv and compare.md of `ncosim compare`
// (sim/analysis/compare.h; columns in results/README.md, "compare.csv and compare.md").
#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "sim/analysis/compare.h"
#include "sim/analysis/compare_stats.h"
#include "sim/files/csv.h"

namespace ncosim::sim {

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
// numbers (the same seed), unpaired where they did not.
std::string pairing_text(const CompareResult& r) {
  const bool swept_seed = std::find(r.base.sweep_keys.begin(), r.base.sweep_keys.end(),
                                    "run.seed") != r.base.sweep_keys.end();
  const std::string paired =
      "paired on the runs both folders have (run r of both drew the same random numbers: common "
      "random numbers), Wilcoxon's signed-rank test of the per-run ratios";
  const std::string unpaired = "Wilcoxon's rank-sum test of the two sets of runs";
  if (swept_seed) {
    return fmt::format("test: per case, {} where the case's run.seed is the same in both, else {}",
                       paired, unpaired);
  }
  if (r.base.seed == r.fresh.seed)
    return fmt::format("test: {}; same seed {}", paired, r.base.seed);
  return fmt::format(
      "test: unpaired, {}: the seeds differ ({} -> {}), so run r is another realisation in each "
      "folder",
      unpaired, r.base.seed, r.fresh.seed);
}

// The typical change with its interval: in % when every end lies within ×0.5 .. ×2, else as
// factors (readable at any size: ×1.2e+160).
std::string change_cell(const CompareRow& row) {
  if (!row.log_ratio || !row.log_low || !row.log_high) return "–";
  const double half = std::log(2.0);
  const auto near = [half](double v) { return std::abs(v) <= half; };  // false for +-inf
  if (near(*row.log_ratio) && near(*row.log_low) && near(*row.log_high)) {
    // Decimals that give the interval's width three significant digits.
    const double width = 100.0 * (std::expm1(*row.log_high) - std::expm1(*row.log_low));
    const int decimals =
        width >= 1e-4 ? std::clamp(2 - static_cast<int>(std::floor(std::log10(width))), 0, 6) : -1;
    const auto pc = [decimals](double v) {
      const double p = 100.0 * std::expm1(v);
      return decimals < 0 ? fmt::format("{:+.3g}", p) : fmt::format("{:+.{}f}", p, decimals);
    };
    return fmt::format("{} % [{}, {}]", pc(*row.log_ratio), pc(*row.log_low), pc(*row.log_high));
  }
  return fmt::format("{} [{}, {}]", ratio_text(*row.log_ratio), ratio_text(*row.log_low),
                     ratio_text(*row.log_high));
}

std::string settings_line(const CompareResult& r) {
  const auto& o = r.options;
  return fmt::format(
      "- verdicts on the typical per-run ratio NEW / BASE (Hodges-Lehmann estimate) with "
      "tolerance {:g}: **worse** when significantly above ×{:g}, **better** when significantly "
      "below ×{:g}, **unchanged** when its interval lies inside (×{:g}, ×{:g}) (an equivalence "
      "test), else **inconclusive** ({}); one-sided tests at alpha = {:g}, {} over {} tested "
      "row(s); each interval at the confidence (`CI`) of the step that decided its row, so that "
      "it reads as its verdict (docs/compare.md)\n",
      o.tolerance, 1.0 + o.tolerance, 1.0 - o.tolerance, 1.0 - o.tolerance, 1.0 + o.tolerance,
      o.allow_inconclusive ? "passes: --allow-inconclusive" : "fails the gate", o.alpha,
      o.holm ? "Holm-corrected" : "no correction", r.tested);
}

}  // namespace

std::string compare_csv(const CompareResult& r) {
  std::string out;
  for (const auto& k : r.base.sweep_keys) out += csv_field(k) + ",";
  out +=
      "estimator,metric,verdict,test,runs_base,runs_new,pairs,base_mean,new_mean,diff,"
      "relative_change,relative_ci_low,relative_ci_high,ci_level,p_worse,p_better,p_unchanged,"
      "note\n";
  auto num = [](std::optional<double> v) {
    return v && std::isfinite(*v) ? fmt::format("{:.6g}", *v) : std::string();
  };
  for (const auto& row : r.rows) {
    for (const auto& l : row.labels) out += csv_field(l) + ",";
    out += fmt::format("{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}\n",
                       csv_field(row.estimator), csv_field(r.options.metric), row.verdict, row.test,
                       row.runs_base, row.runs_new, row.pairs, num(row.base_mean),
                       num(row.new_mean), num(row.diff), num(row.relative), num(row.relative_low),
                       num(row.relative_high), num(row.ci_level), num(row.p_worse),
                       num(row.p_better), num(row.p_unchanged), csv_field(row.note));
  }
  return out;
}

std::string compare_markdown(const CompareResult& r) {
  const auto& o = r.options;
  std::string out = fmt::format("# ncosim compare: {}\n\n", o.metric);
  out += fmt::format("- BASE `{}`: {} (seed {}, scenario_hash {})\n", r.base.dir, r.base.scenario,
                     r.base.seed, r.base.scenario_hash);
  out += fmt::format("- NEW `{}`: {} (seed {}, scenario_hash {})\n", r.fresh.dir, r.fresh.scenario,
                     r.fresh.seed, r.fresh.scenario_hash);
  out += settings_line(r);
  if (!r.differences.empty()) {
    out += "- BASE -> NEW differ in:\n";
    for (const auto& d : r.differences) out += fmt::format("  - {}\n", d);
  }
  out += fmt::format("- {}\n", pairing_text(r));
  for (const auto& w : r.warnings) out += fmt::format("- warning: {}\n", w);
  out += "\n|";
  for (const auto& k : r.base.sweep_keys) out += fmt::format(" {} |", md_cell(k));
  out +=
      " estimator | verdict | test | runs | BASE | NEW | change [interval] | CI | p worse | "
      "p better | p unchanged | note |\n|";
  for (std::size_t i = 0; i < r.base.sweep_keys.size() + 12; ++i) out += "---|";
  out += "\n";
  auto g = [](std::optional<double> v, const char* f) {
    return v && std::isfinite(*v) ? fmt::format(fmt::runtime(f), *v) : std::string("–");
  };
  for (const auto& row : r.rows) {
    out += "|";
    for (const auto& l : row.labels) out += fmt::format(" {} |", md_cell(l));
    const std::string verdict = row.verdict == "worse" ? "**worse**" : row.verdict;
    const std::string ci = row.ci_level ? fmt::format("{:.4g} %", 100.0 * *row.ci_level) : "–";
    out += fmt::format(" {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |\n",
                       md_cell(row.estimator), verdict, row.test,
                       row.test == "paired" ? std::to_string(row.pairs)
                                            : fmt::format("{} / {}", row.runs_base, row.runs_new),
                       g(row.base_mean, "{:.6g}"), g(row.new_mean, "{:.6g}"), change_cell(row), ci,
                       g(row.p_worse, "{:.3g}"), g(row.p_better, "{:.3g}"),
                       g(row.p_unchanged, "{:.3g}"), md_cell(row.note));
  }
  out += fmt::format(
      "\n{} worse, {} better, {} unchanged, {} inconclusive, {} not comparable: exit {}\n", r.worse,
      r.better, r.unchanged, r.inconclusive, r.not_comparable, r.exit_code());
  if (r.inconclusive > 0 && r.worse == 0) {
    out += o.allow_inconclusive
               ? "- inconclusive rows pass (--allow-inconclusive)\n"
               : "- an inconclusive row fails the gate (exit 4): more runs narrow its interval; "
                 "--allow-inconclusive passes it\n";
  }
  return out;
}

}  // namespace ncosim::sim
