// sim/cmd/ladder_report.cc — the summary, ladder.csv and ladder.md of `ncosim ladder`
// (sim/cmd/ladder_report.h).
#include "sim/cmd/ladder_report.h"

#include <fmt/format.h>

#include <cmath>

#include "sim/analysis/output.h"

namespace ncosim::sim {

namespace {

// The verdict that can put a row inside the band (sim/analysis/compare.h).
constexpr const char* kUnchanged = "unchanged";

std::string opt(const std::optional<double>& v, const char* f = "{:.6g}") {
  return v && std::isfinite(*v) ? fmt::format(fmt::runtime(f), *v) : std::string();
}

// "+12.3 % [+8.1, +16.5]" (the relative change of the rung's mse against the network's).
std::string change_text(const CompareRow& row) {
  if (!row.relative) return "-";
  std::string s = fmt::format("{:+.1f} %", 100.0 * *row.relative);
  if (row.relative_low && row.relative_high)
    s += fmt::format(" [{:+.1f}, {:+.1f}]", 100.0 * *row.relative_low, 100.0 * *row.relative_high);
  return s;
}

std::string speed_text(const LadderReport& r, const Rung& rung) {
  const double net = r.rungs.front().wall;
  if (&rung == &r.rungs.front()) return fmt::format("{:.3g} s", net);
  if (!(rung.wall > 0.0)) return "-";
  return fmt::format("{:.3g} s, {:.3g}x", rung.wall, net / rung.wall);
}

// Per surrogate, where it leaves the band: the rows not inside it (`md`: as a Markdown list).
std::string band_text(const LadderReport& r, bool md) {
  std::string s = fmt::format(
      "\nWhere each surrogate leaves the band (the network's mse +-{:.3g} %: compare's verdict "
      "unchanged, its 95 % interval inside the band; paired at alpha {:.3g}, same seed and "
      "runs):\n",
      100.0 * r.tolerance, r.alpha);
  std::string lowest;
  for (std::size_t i = 1; i < r.rungs.size(); ++i) {
    const Rung& rung = r.rungs[i];
    std::string out;
    for (const auto& row : rung.compare.rows) {
      const std::string where = band_verdict(row, r.tolerance);
      if (where == kInside) continue;
      out += fmt::format("{}{} {} ({})", out.empty() ? "" : ", ", row.estimator, where,
                         change_text(row));
    }
    if (out.empty() && lowest.empty()) lowest = rung.name;
    s += fmt::format(fmt::runtime(md ? "- {}: {}{}\n" : "  {:<16} {}{}\n"), rung.name,
                     out.empty() ? "inside it for every estimator" : "leaves it: " + out,
                     rung.note.empty() ? "" : fmt::format("  [{}]", rung.note));
  }
  s += lowest.empty()
           ? "No surrogate is inside the band for every estimator.\n"
           : fmt::format("The lowest rung inside the band for every estimator: {}.\n", lowest);
  return s;
}

}  // namespace

std::string link_summary(const std::string& name, const FitSet& set,
                         const std::vector<double>& design_pmf) {
  std::string pmf;
  for (std::size_t d = 0; d < design_pmf.size() && d < 6; ++d)
    pmf += fmt::format("{}{:.4g}", d ? ", " : "", design_pmf[d]);
  if (design_pmf.size() > 6) pmf += fmt::format(", ... ({} values)", design_pmf.size());
  return fmt::format(
      "{}: {} scored packets, loss {:.4g}, delays 0 .. {}; {} selects {}{}; design_pmf [{}]", name,
      set.packets, static_cast<double>(set.lost) / static_cast<double>(set.packets),
      set.longest_delay, set.criterion, set.fits[set.best].family,
      set.fits[set.best].converged ? "" : " (not converged)", pmf);
}

std::string band_verdict(const CompareRow& row, double tolerance) {
  if (row.verdict != kUnchanged) return row.verdict;
  const bool inside = row.relative_low && row.relative_high && *row.relative_low >= -tolerance &&
                      *row.relative_high <= tolerance;
  return inside ? kInside : "inconclusive";
}

std::string ladder_summary(const LadderReport& r) {
  std::string s = fmt::format(
      "ncosim ladder {}: {} network link(s) recorded ({} runs x {} periods, seed {}) in {:.3g} s "
      "and fitted in {:.3g} s\n",
      r.file, r.links.size(), r.runs, r.periods, r.seed, r.record_seconds, r.fit_seconds);
  for (const auto& l : r.links) s += "  " + l + "\n";
  s += fmt::format("\n{:<16} {:<20} {:>12} {:>12} {:>26} {:>14} {:>16}\n", "rung", "estimator",
                   "network mse", "rung mse", "change % [95 % CI]", "band", "wall, speed-up");
  for (std::size_t i = 0; i < r.rungs.size(); ++i) {
    const Rung& rung = r.rungs[i];
    if (i == 0) {
      s += fmt::format("{:<16} {:<20} {:>12} {:>12} {:>26} {:>14} {:>16}\n", rung.name, "", "", "",
                       "", "", speed_text(r, rung));
      continue;
    }
    for (std::size_t k = 0; k < rung.compare.rows.size(); ++k) {
      const auto& row = rung.compare.rows[k];
      s +=
          fmt::format("{:<16} {:<20} {:>12} {:>12} {:>26} {:>14} {:>16}\n", k == 0 ? rung.name : "",
                      row.estimator, opt(row.base_mean), opt(row.new_mean), change_text(row),
                      band_verdict(row, r.tolerance), k == 0 ? speed_text(r, rung) : "");
    }
  }
  s += band_text(r, false);
  std::string names;
  for (const auto& rung : r.rungs) names += (names.empty() ? "" : ", ") + rung.name + ".toml";
  s += fmt::format(
      "\nwritten to {}/: {} (ordinary scenarios: `ncosim run` them), ladder.csv, ladder.md, "
      "traces/, fits/, runs/, compare/\n",
      r.out, names);
  return s;
}

std::string ladder_csv(const LadderReport& r) {
  std::string csv =
      "rung,estimator,verdict,band,test,pairs,network_mse,rung_mse,change,change_ci95_low,"
      "change_ci95_high,wall_seconds,speedup,note\n";
  const double net = r.rungs.empty() ? 0.0 : r.rungs.front().wall;
  for (std::size_t i = 0; i < r.rungs.size(); ++i) {
    const Rung& rung = r.rungs[i];
    const std::string speed =
        rung.wall > 0.0 ? fmt::format("{:.6g}", net / rung.wall) : std::string();
    if (i == 0) {
      for (const auto& row :
           r.rungs.size() > 1 ? r.rungs[1].compare.rows : std::vector<CompareRow>{}) {
        csv += fmt::format("network,{},,,,,{},{},,,,{:.6g},1,\n", csv_field(row.estimator),
                           opt(row.base_mean), opt(row.base_mean), rung.wall);
      }
      continue;
    }
    for (const auto& row : rung.compare.rows) {
      csv += fmt::format("{},{},{},{},{},{},{},{},{},{},{},{:.6g},{},{}\n", rung.name,
                         csv_field(row.estimator), csv_field(row.verdict),
                         band_verdict(row, r.tolerance), row.test, row.pairs, opt(row.base_mean),
                         opt(row.new_mean), opt(row.relative), opt(row.relative_low),
                         opt(row.relative_high), rung.wall, speed, csv_field(rung.note));
    }
  }
  return csv;
}

std::string ladder_markdown(const LadderReport& r) {
  std::string md = fmt::format(
      "# Fidelity ladder of `{}`\n\n{} runs x {} periods, seed {}; the band: the network's mse "
      "+-{:.3g} % (compare at alpha {:.3g}).\n\n",
      r.file, r.runs, r.periods, r.seed, 100.0 * r.tolerance, r.alpha);
  for (const auto& l : r.links) md += "- " + l + "\n";
  md +=
      "\n| rung | estimator | network mse | rung mse | change % [95 % CI] | compare | band | "
      "wall s | speed-up |\n|---|---|---|---|---|---|---|---|---|\n";
  for (std::size_t i = 1; i < r.rungs.size(); ++i) {
    const Rung& rung = r.rungs[i];
    for (const auto& row : rung.compare.rows) {
      md += fmt::format("| {} | {} | {} | {} | {} | {} | {} | {:.3g} | {:.3g} |\n", rung.name,
                        row.estimator, opt(row.base_mean), opt(row.new_mean), change_text(row),
                        row.verdict, band_verdict(row, r.tolerance), rung.wall,
                        rung.wall > 0.0 ? r.rungs.front().wall / rung.wall : 0.0);
    }
  }
  md += fmt::format("\nThe network's campaign: {:.3g} s of simulation.\n", r.rungs.front().wall);
  return md + band_text(r, true);
}

}  // namespace ncosim::sim
