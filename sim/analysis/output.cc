// sim/analysis/output.cc — summary statistics and the result files.
#include "sim/analysis/output.h"

#include <fmt/format.h>
#include <unistd.h>

#include <algorithm>
#include <boost/math/distributions/students_t.hpp>
#include <cmath>
#include <filesystem>
#include <fstream>

#include "sim/analysis/validity.h"
#include "sim/files/output_set.h"
#include "sim/run/physical.h"

namespace ncosim::sim {

std::optional<double> ci95_half_width(const std::vector<double>& values) {
  const std::size_t n = values.size();
  if (n < 2) return std::nullopt;
  double mean = 0.0;
  for (double v : values) mean += v;
  mean /= static_cast<double>(n);
  double ss = 0.0;
  for (double v : values) ss += (v - mean) * (v - mean);
  const double sd = std::sqrt(ss / static_cast<double>(n - 1));
  const boost::math::students_t dist(static_cast<double>(n - 1));
  const double t = boost::math::quantile(boost::math::complement(dist, 0.025));
  return t * sd / std::sqrt(static_cast<double>(n));
}

namespace {

std::optional<double> finite(double v) {
  if (!std::isfinite(v)) return std::nullopt;
  return v;
}

void add_consistency(ConsistencySums& s, const EstimatorRunMetrics& m) {
  if (m.diverged) return;
  s.nees += m.nees;
  s.nees_count += m.nees_count;
  if (m.nees_count > 0) ++s.nees_runs;
  s.nis += m.nis;
  s.nis_dof += m.nis_dof;
  s.nis_count += m.nis_count;
}

double mean_of(const std::vector<double>& v) {
  double s = 0.0;
  for (double x : v) s += x;
  return s / static_cast<double>(v.size());
}

// One estimator's sums over the runs of a campaign.
struct RunTotals {
  std::vector<double> mse, mse_ext, mde;  // per run that did not diverge
  std::vector<std::vector<double>> root;  // per state, each such run's RMSE
  std::vector<double> state_sse;          // per state, over those runs
  std::int64_t count = 0, used = 0, taken = 0, diverged = 0;
  std::int64_t failed = 0;  // runs whose process died (status network_failure; also diverged)
  double flops = 0.0, flop_periods = 0.0;
  std::string run_status = "ok";  // the first non-ok status of a run that did not diverge
  ConsistencySums consistency;
};

// Estimator e's totals over the campaign's runs; its mode confusion counts are summed into row.
RunTotals run_totals(const CampaignResult& result, std::size_t e, Eigen::Index n, SummaryRow& row) {
  RunTotals t;
  t.root.resize(static_cast<std::size_t>(n));
  t.state_sse.assign(static_cast<std::size_t>(n), 0.0);
  for (const auto& run : result.runs) {
    const EstimatorRunMetrics& m = run[e];
    add_consistency(t.consistency, m);
    t.used += m.samples_used;
    t.taken += m.samples_taken;
    if (m.counters) {
      t.flops += m.counters->flops;
      t.flop_periods += static_cast<double>(m.counters->periods);
    }
    if (m.diverged) {
      ++t.diverged;
      if (m.status == "network_failure") ++t.failed;
      continue;
    }
    if (m.status != "ok" && t.run_status == "ok") t.run_status = m.status;
    t.mse.push_back(m.sse / static_cast<double>(m.count));
    t.mse_ext.push_back(m.sse_ext / static_cast<double>(m.count));
    for (std::size_t i = 0; i < t.state_sse.size(); ++i) {
      t.state_sse[i] += m.sse_state[i];
      t.root[i].push_back(std::sqrt(m.sse_state[i] / static_cast<double>(m.count)));
    }
    t.count += m.count;
    if (m.mode_count > 0)
      t.mde.push_back(100.0 * static_cast<double>(m.mode_errors) /
                      static_cast<double>(m.mode_count));
    if (!m.confusion.empty()) {
      row.confusion.resize(m.confusion.size(), 0);
      for (std::size_t c = 0; c < m.confusion.size(); ++c) row.confusion[c] += m.confusion[c];
    }
  }
  return t;
}

// The error statistics of a row none of whose runs diverged: MSE, per-state RMSE and ERMSE, and
// the mode detection error, each with its CI.
void set_error_statistics(const RunTotals& t, bool extended, std::size_t runs, SummaryRow& row) {
  row.mse = finite(mean_of(t.mse));
  row.mse_ci95 = ci95_half_width(t.mse);
  if (extended) {
    row.mse_ext = finite(mean_of(t.mse_ext));
    row.mse_ext_ci95 = ci95_half_width(t.mse_ext);
  }
  for (double s : t.state_sse)
    row.rmse.push_back(finite(std::sqrt(s / static_cast<double>(t.count))));
  for (const auto& r : t.root) {
    row.ermse.push_back(finite(mean_of(r)));
    row.ermse_ci95.push_back(ci95_half_width(r));
  }
  // Every run scores the same periods, so the mean of per-run MDEs is the pooled share.
  if (!t.mde.empty() && t.mde.size() == runs) {
    row.mde_percent = mean_of(t.mde);
    row.mde_ci95 = ci95_half_width(t.mde);
    row.mde_run_min = *std::min_element(t.mde.begin(), t.mde.end());
    row.mde_run_max = *std::max_element(t.mde.begin(), t.mde.end());
  }
}

// The sensors' transmissions per scored period, over every run of estimator e.
void set_sent_per_period(const Scenario& sc, const CampaignResult& result, std::size_t e,
                         SummaryRow& row) {
  std::int64_t sent = 0, runs = 0;
  for (const auto& run : result.runs) {
    if (run[e].status == "network_failure") continue;  // its process died: nothing was counted
    ++runs;
    for (const auto v : run[e].sensor_sent) sent += v;
  }
  const double periods =
      static_cast<double>(sc.run.periods - sc.run.warmup) * static_cast<double>(runs);
  if (periods > 0) row.sent_per_period = static_cast<double>(sent) / periods;
}

// The per-run values kept for comparisons (none of a row with a diverged run) and the run ids.
void set_per_run(const Scenario& sc, const CampaignResult& result, const RunTotals& t,
                 SummaryRow& row) {
  if (t.diverged == 0) {
    row.per_run.mse = t.mse;
    if (row.mse_ext) row.per_run.mse_ext = t.mse_ext;
    if (row.mde_percent) row.per_run.mde = t.mde;
  }
  row.per_run.seed = sc.run.seed;
  for (std::size_t r = 0; r < result.runs.size(); ++r) {
    row.per_run.run.push_back(r < result.run_ids.size() ? result.run_ids[r] : r);
  }
}

// The summary row of estimator e over the campaign's runs.
SummaryRow summary_row(const Scenario& sc, const CampaignResult& result, std::size_t e,
                       const std::vector<std::string>& sweep_labels) {
  const Eigen::Index n = sc.model.plant.n();
  const auto& entry = sc.estimators[e];
  const auto& rep = entry.design->report();
  SummaryRow row;
  row.sweep_labels = sweep_labels;
  row.estimator = entry.name;
  row.kind = entry.kind;
  row.runs = static_cast<std::int64_t>(result.runs.size());
  const std::string design_status = rep.status == "ok" ? "ok" : "design_" + rep.status;
  const RunTotals t = run_totals(result, e, n, row);
  // Precedence: a failed design (it says why the rest went wrong), a run whose process died (its
  // record counts as diverged, but the estimator did not diverge), divergence, run status.
  const std::string status = design_status != "ok" ? design_status
                             : t.failed > 0        ? "network_failure"
                             : t.diverged > 0      ? "diverged"
                                                   : t.run_status;
  if (t.diverged == 0)
    set_error_statistics(t, entry.design->extended_size() > 0, result.runs.size(), row);
  row.rmse.resize(static_cast<std::size_t>(n));
  row.ermse.resize(static_cast<std::size_t>(n));
  row.ermse_ci95.resize(static_cast<std::size_t>(n));
  if (!row.confusion.empty()) row.modes = sc.model.mode_count();
  row.flops_per_period = entry.design->flops_per_period();
  row.stored_gains = rep.stored_gains;
  row.ns_per_period = finite(result.ns_per_period.at(e));
  row.predicted_mse_ext = rep.predicted_mse_ext;
  if (t.taken > 0) row.delivered_ratio = static_cast<double>(t.used) / static_cast<double>(t.taken);
  row.status = status;
  row.predicted_mse = rep.predicted_mse;
  if (t.flop_periods > 0) row.flops_mean = t.flops / t.flop_periods;
  set_sent_per_period(sc, result, e, row);
  set_per_run(sc, result, t, row);
  row.model_check = model_check_note(sc, e, row);
  if (t.diverged == 0) {
    row.nees = nees_stat(t.consistency, n);
    row.nis = nis_stat(t.consistency);
    row.consistency = consistency_note(row.nees, row.nis);
  }
  row.expected_status = entry.expected_status;
  return row;
}

}  // namespace

std::vector<SummaryRow> summarise(const Scenario& sc, const CampaignResult& result,
                                  const std::vector<std::string>& sweep_labels) {
  std::vector<SummaryRow> rows;
  for (std::size_t e = 0; e < sc.estimators.size(); ++e)
    rows.push_back(summary_row(sc, result, e, sweep_labels));
  add_paired_within(rows, reference_row_index(sc, rows));
  return rows;
}

std::vector<std::string> summary_columns(const std::vector<SweepAxis>& sweeps, Eigen::Index n) {
  std::vector<std::string> cols;
  for (const auto& s : sweeps) cols.push_back(s.key);
  for (const char* c : {"estimator", "kind", "runs", "mse", "mse_ci95", "mse_ext", "mse_ext_ci95"})
    cols.push_back(c);
  for (Eigen::Index i = 0; i < n; ++i) cols.push_back(fmt::format("rmse_x{}", i + 1));
  for (const char* c : {"mde_percent", "flops_per_period", "stored_gains", "ns_per_period",
                        "predicted_mse_ext", "delivered_ratio", "status", "predicted_mse",
                        "flops_mean", "mde_ci95", "sent_per_period"}) {
    cols.push_back(c);
  }
  for (Eigen::Index i = 0; i < n; ++i) cols.push_back(fmt::format("ermse_x{}", i + 1));
  for (Eigen::Index i = 0; i < n; ++i) cols.push_back(fmt::format("ermse_x{}_ci95", i + 1));
  for (auto& c : paired_column_names(!sweeps.empty())) cols.push_back(std::move(c));
  cols.emplace_back("model_check");
  return cols;
}

namespace {

std::vector<std::string> row_cells(const SummaryRow& r) {
  std::vector<std::string> cells = r.sweep_labels;
  cells.push_back(r.estimator);
  cells.push_back(r.kind);
  cells.push_back(std::to_string(r.runs));
  cells.push_back(fmt_number(r.mse));
  cells.push_back(fmt_number(r.mse_ci95));
  cells.push_back(fmt_number(r.mse_ext));
  cells.push_back(fmt_number(r.mse_ext_ci95));
  for (const auto& v : r.rmse) cells.push_back(fmt_number(v));
  cells.push_back(fmt_number(r.mde_percent));
  cells.push_back(r.flops_per_period ? fmt::format("{:.0f}", *r.flops_per_period) : "");
  cells.push_back(r.stored_gains ? std::to_string(*r.stored_gains) : "");
  cells.push_back(r.ns_per_period ? fmt::format("{:.1f}", *r.ns_per_period) : "");
  cells.push_back(fmt_number(r.predicted_mse_ext));
  cells.push_back(fmt_number(r.delivered_ratio));
  cells.push_back(r.status);
  cells.push_back(fmt_number(r.predicted_mse));
  cells.push_back(r.flops_mean ? fmt::format("{:.0f}", *r.flops_mean) : "");
  cells.push_back(fmt_number(r.mde_ci95));
  cells.push_back(fmt_number(r.sent_per_period));
  for (const auto& v : r.ermse) cells.push_back(fmt_number(v));
  for (const auto& v : r.ermse_ci95) cells.push_back(fmt_number(v));
  for (auto& c : paired_cells(r.paired, !r.sweep_labels.empty())) cells.push_back(std::move(c));
  cells.push_back(r.model_check);
  return cells;
}

}  // namespace

std::vector<std::string> summary_csv_columns(const std::vector<SweepAxis>& sweeps, Eigen::Index n,
                                             bool stop) {
  auto cols = summary_columns(sweeps, n);
  if (stop) cols.emplace_back("stop");  // --target-ci campaigns only
  cols.emplace_back("expected_status");
  for (const char* c : {"nees", "nees_lo", "nees_hi", "nis", "nis_lo", "nis_hi", "consistency"})
    cols.push_back(c);
  return cols;
}

SummaryText summary_text(const std::vector<SweepAxis>& sweeps, const std::vector<SummaryRow>& rows,
                         Eigen::Index n) {
  const bool stop =
      std::any_of(rows.begin(), rows.end(), [](const SummaryRow& r) { return !r.stop.empty(); });
  SummaryText t{summary_csv_columns(sweeps, n, stop), {}};
  for (const auto& r : rows) {
    auto cells = row_cells(r);
    if (stop) cells.push_back(r.stop);
    cells.push_back(r.expected_status);
    for (const auto& st : {r.nees, r.nis}) {  // filter consistency (sim/analysis/consistency.h)
      cells.push_back(st ? fmt_number(st->mean) : "");
      cells.push_back(st ? fmt_number(st->lo) : "");
      cells.push_back(st ? fmt_number(st->hi) : "");
    }
    cells.push_back(r.consistency);
    t.cells.push_back(std::move(cells));
  }
  return t;
}

std::string summary_text_csv(const SummaryText& t) {
  auto line = [](const std::vector<std::string>& cells) {
    std::string out;
    for (std::size_t i = 0; i < cells.size(); ++i) out += (i ? "," : "") + csv_field(cells[i]);
    return out + "\n";
  };
  std::string out = line(t.header);
  for (const auto& c : t.cells) out += line(c);
  return out;
}

std::string summary_csv(const std::vector<SweepAxis>& sweeps, const std::vector<SummaryRow>& rows,
                        Eigen::Index n) {
  return summary_text_csv(summary_text(sweeps, rows, n));
}

std::string confusion_csv(const std::vector<SweepAxis>& sweeps,
                          const std::vector<SummaryRow>& rows) {
  std::string out;
  for (const auto& s : sweeps) out += csv_field(s.key) + ",";
  out += "estimator,true_mode,estimated_mode,count,share_of_true\n";
  for (const auto& r : rows) {
    if (r.confusion.empty()) continue;
    const int s = r.modes;
    for (int t = 0; t < s; ++t) {
      std::int64_t total = 0;
      for (int e = 0; e < s; ++e) total += r.confusion[static_cast<std::size_t>(t * s + e)];
      for (int e = 0; e < s; ++e) {
        const std::int64_t c = r.confusion[static_cast<std::size_t>(t * s + e)];
        for (const auto& l : r.sweep_labels) out += csv_field(l) + ",";
        out += fmt::format(
            "{},{},{},{},{}\n", csv_field(r.estimator), t, e, c,
            total > 0 ? fmt_number(static_cast<double>(c) / static_cast<double>(total)) : "");
      }
    }
  }
  return out;
}

namespace {

// A markdown table with every column padded to its widest cell (width in code points, so "±" and
// "–" count once).
std::string markdown_table(const std::vector<std::string>& head,
                           const std::vector<std::vector<std::string>>& body) {
  auto width = [](const std::string& s) {
    std::size_t w = 0;
    for (unsigned char ch : s) w += (ch & 0xC0) != 0x80;
    return w;
  };
  std::vector<std::size_t> wid(head.size(), 3);
  for (std::size_t i = 0; i < head.size(); ++i) wid[i] = std::max(wid[i], width(head[i]));
  for (const auto& r : body) {
    for (std::size_t i = 0; i < r.size(); ++i) wid[i] = std::max(wid[i], width(r[i]));
  }
  auto line = [&](const std::vector<std::string>& cells) {
    std::string out = "|";
    for (std::size_t i = 0; i < cells.size(); ++i) {
      out += " " + cells[i] + std::string(wid[i] - width(cells[i]), ' ') + " |";
    }
    return out + "\n";
  };
  std::string out = line(head);
  std::string sep = "|";
  for (std::size_t i = 0; i < head.size(); ++i) sep += std::string(wid[i] + 2, '-') + "|";
  out += sep + "\n";
  for (const auto& r : body) out += line(r);
  return out;
}

// The note under summary.md's table naming the paired columns' references ("" without rows).
std::string paired_note(const std::vector<SummaryRow>& rows, bool swept) {
  // Name the references under the table (one line; the reference may differ between cases).
  std::vector<std::string> refs;
  for (const auto& r : rows) {
    if (std::find(refs.begin(), refs.end(), r.paired.reference) == refs.end())
      refs.push_back(r.paired.reference);
  }
  std::string names;
  for (const auto& ref : refs) names += (names.empty() ? "" : ", ") + fmt::format("\"{}\"", ref);
  std::string out;
  if (!rows.empty()) {
    out += fmt::format(
        "\nPaired columns: each row minus the reference estimator {} of its case, per run on the "
        "same "
        "realisation (common random numbers); ratio = row / reference.",
        names);
    if (swept)
      out += fmt::format(" Δ vs ref. case: against the same estimator in the case {}.",
                         rows.front().paired.reference_case);
    out += " Columns mse_diff.. in summary.csv." + paired_reference_note(rows) + "\n";
  }
  return out;
}

}  // namespace

std::string summary_markdown(const std::string& title, const std::vector<SweepAxis>& sweeps,
                             const std::vector<SummaryRow>& rows, Eigen::Index n) {
  // Readable columns: mse ± ci, mse_ext ± ci, predicted, FLOPs, gains, ns, delivered, status.
  std::vector<std::string> head;
  for (const auto& s : sweeps) head.push_back(s.key);
  for (const char* c : {"estimator", "mse ± 95% CI", "mse_ext ± 95% CI", "predicted mse_ext"})
    head.push_back(c);
  for (Eigen::Index i = 0; i < n; ++i) head.push_back(fmt::format("rmse_x{}", i + 1));
  bool modes = false;
  for (const auto& r : rows) modes = modes || r.mde_percent.has_value();
  if (modes) {
    head.push_back("MDE % ± 95% CI");
    for (Eigen::Index i = 0; i < n; ++i) head.push_back(fmt::format("E{{RMSE{}}} ± 95% CI", i + 1));
  }
  for (const char* c : {"FLOPs", "gains", "ns/period", "delivered", "status"}) head.push_back(c);
  // Paired columns (sim/analysis/paired.h): against the reference estimator, and with sweeps
  // against the same estimator in the reference case.
  const bool swept = !sweeps.empty();
  head.push_back("Δmse vs ref. (paired) ± 95% CI");
  head.push_back("mse ratio ± 95% CI");
  if (modes) head.push_back("ΔMDE pp vs ref. ± 95% CI");
  if (swept) head.push_back("Δmse vs ref. case ± 95% CI");
  bool checks = false;
  for (const auto& r : rows) checks = checks || !r.model_check.empty();
  if (checks) head.push_back("model check");
  auto pm = [](std::optional<double> v, std::optional<double> ci) {
    if (!v) return std::string("–");
    return ci ? fmt::format("{:.4g} ± {:.2g}", *v, *ci) : fmt::format("{:.4g}", *v);
  };
  auto num = [](std::optional<double> v, const char* f) {
    return v && std::isfinite(*v) ? fmt::format(fmt::runtime(f), *v) : std::string("–");
  };
  std::vector<std::vector<std::string>> body;
  for (const auto& r : rows) {
    std::vector<std::string> c = r.sweep_labels;
    c.push_back(r.estimator);
    c.push_back(pm(r.mse, r.mse_ci95));
    c.push_back(pm(r.mse_ext, r.mse_ext_ci95));
    c.push_back(num(r.predicted_mse_ext, "{:.4g}"));
    for (const auto& v : r.rmse) c.push_back(num(v, "{:.4g}"));
    if (modes) {
      c.push_back(pm(r.mde_percent, r.mde_ci95));
      for (std::size_t i = 0; i < r.ermse.size(); ++i) c.push_back(pm(r.ermse[i], r.ermse_ci95[i]));
    }
    c.push_back(num(r.flops_per_period, "{:.0f}"));
    c.push_back(r.stored_gains ? std::to_string(*r.stored_gains) : "–");
    c.push_back(num(r.ns_per_period, "{:.0f}"));
    c.push_back(num(r.delivered_ratio, "{:.3f}"));
    c.push_back(status_text(r));
    c.push_back(pm(r.paired.mse.diff, r.paired.mse.diff_ci95));
    c.push_back(pm(r.paired.mse.ratio, r.paired.mse.ratio_ci95));
    if (modes) c.push_back(pm(r.paired.mde.diff, r.paired.mde.diff_ci95));
    if (swept) c.push_back(pm(r.paired.case_mse.diff, r.paired.case_mse.diff_ci95));
    if (checks) c.push_back(r.model_check.empty() ? "–" : r.model_check);
    body.push_back(std::move(c));
  }
  std::string out = fmt::format("# {}\n\n", title) + markdown_table(head, body);
  out += paired_note(rows, swept);
  return out;
}

std::string runs_csv(const std::vector<SweepAxis>& sweeps,
                     const std::vector<std::vector<std::string>>& labels,
                     const std::vector<const Scenario*>& scenarios,
                     const std::vector<const CampaignResult*>& results) {
  std::string out;
  for (const auto& s : sweeps) out += csv_field(s.key) + ",";
  const Eigen::Index n = scenarios.empty() ? 0 : scenarios.front()->model.plant.n();
  out +=
      "run,estimator,mse,mse_ext,periods,samples_used,samples_taken,diverged,status,flops_mean,"
      "late_samples,"
      "duplicate_samples,mde_percent";
  for (Eigen::Index i = 0; i < n; ++i) out += fmt::format(",rmse_x{}", i + 1);
  out += ",nees,nis\n";
  for (std::size_t c = 0; c < scenarios.size(); ++c) {
    const Scenario& sc = *scenarios[c];
    for (std::size_t r = 0; r < results[c]->runs.size(); ++r) {
      for (std::size_t e = 0; e < sc.estimators.size(); ++e) {
        const auto& m = results[c]->runs[r][e];
        for (const auto& l : labels[c]) out += csv_field(l) + ",";
        const bool has_ext = sc.estimators[e].design->extended_size() > 0;
        const bool ok = !m.diverged && m.count > 0;
        const auto& cnt = m.counters;
        const std::uint64_t run_id = results[c]->run_ids.empty() ? r : results[c]->run_ids[r];
        out += fmt::format(
            "{},{},{},{},{},{},{},{},{},{},{},{}", run_id, csv_field(sc.estimators[e].name),
            ok ? fmt_number(m.sse / static_cast<double>(m.count)) : "",
            ok && has_ext ? fmt_number(m.sse_ext / static_cast<double>(m.count)) : "", m.count,
            m.samples_used, m.samples_taken, m.diverged ? 1 : 0, csv_field(m.status),
            cnt && cnt->periods > 0
                ? fmt::format("{:.0f}", cnt->flops / static_cast<double>(cnt->periods))
                : "",
            cnt ? std::to_string(cnt->late) : "", cnt ? std::to_string(cnt->duplicates) : "");
        out += "," + (m.mode_count > 0 ? fmt_number(100.0 * static_cast<double>(m.mode_errors) /
                                                    static_cast<double>(m.mode_count))
                                       : std::string());
        for (Eigen::Index i = 0; i < n && i < static_cast<Eigen::Index>(m.sse_state.size()); ++i) {
          out += "," + (ok ? fmt_number(std::sqrt(m.sse_state[static_cast<std::size_t>(i)] /
                                                  static_cast<double>(m.count)))
                           : std::string());
        }
        // The run's average NEES per period and NIS per update (sim/analysis/consistency.h).
        out +=
            "," + (ok && m.nees_count > 0 ? fmt_number(m.nees / static_cast<double>(m.nees_count))
                                          : std::string());
        out += "," + (ok && m.nis_count > 0 ? fmt_number(m.nis / static_cast<double>(m.nis_count))
                                            : std::string());
        out += "\n";
      }
    }
  }
  return out;
}

namespace {

nlohmann::json opt_json(const std::optional<double>& v) {
  if (!v || !std::isfinite(*v)) return nullptr;
  return *v;
}

}  // namespace

nlohmann::json design_json(const LoadedScenario& loaded) {
  nlohmann::json cases = nlohmann::json::array();
  for (const auto& c : loaded.cases) {
    nlohmann::json ests = nlohmann::json::array();
    for (const auto& e : c.scenario->estimators) {
      const auto& r = e.design->report();
      nlohmann::json j;
      j["name"] = e.name;
      j["kind"] = e.kind;
      j["method"] = r.method;
      j["design_seconds"] = r.design_seconds;
      j["stored_gains"] =
          r.stored_gains ? nlohmann::json(*r.stored_gains) : nlohmann::json(nullptr);
      j["predicted_mse"] = opt_json(r.predicted_mse);
      j["predicted_mse_ext"] = opt_json(r.predicted_mse_ext);
      j["stable"] = r.stable ? nlohmann::json(*r.stable) : nlohmann::json(nullptr);
      j["status"] = r.status;
      j["flops_per_period"] = opt_json(e.design->flops_per_period());
      for (const auto& [k, v] : r.extra.items()) j[k] = v;
      ests.push_back(std::move(j));
    }
    if (loaded.sweeps.empty()) return nlohmann::json{{"estimators", ests}};
    nlohmann::json sweep = nlohmann::json::object();
    for (std::size_t a = 0; a < loaded.sweeps.size(); ++a)
      sweep[loaded.sweeps[a].key] = c.labels[a];
    cases.push_back({{"sweep", sweep}, {"estimators", ests}});
  }
  // With sweeps: the first case's estimators stay under "estimators" (the contract's shape),
  // and every case is listed under "cases".
  return nlohmann::json{{"estimators", cases.front()["estimators"]}, {"cases", cases}};
}

std::string design_csv(const LoadedScenario& loaded) {
  std::string out;
  std::vector<std::string> cols;
  for (const auto& s : loaded.sweeps) cols.push_back(s.key);
  for (const char* c : {"estimator", "kind", "method", "predicted_mse", "predicted_mse_ext",
                        "stored_gains", "flops_per_period", "p0", "design_seconds", "status",
                        "predicted_mse_paper_eq28_erroneous"}) {
    cols.push_back(c);
  }
  for (std::size_t i = 0; i < cols.size(); ++i) out += (i ? "," : "") + csv_field(cols[i]);
  out += "\n";
  for (const auto& c : loaded.cases) {
    for (const auto& e : c.scenario->estimators) {
      const auto& r = e.design->report();
      std::vector<std::string> cells = c.labels;
      cells.push_back(e.name);
      cells.push_back(e.kind);
      cells.push_back(r.method);
      auto precise = [](std::optional<double> v) {
        return v && std::isfinite(*v) ? fmt::format("{:.10g}", *v) : std::string();
      };
      cells.push_back(precise(r.predicted_mse));
      cells.push_back(precise(r.predicted_mse_ext));
      cells.push_back(r.stored_gains ? std::to_string(*r.stored_gains) : "");
      const auto flops = e.design->flops_per_period();
      cells.push_back(flops ? fmt::format("{:.0f}", *flops) : "");
      const auto p0 = r.extra.find("p0");
      cells.push_back(p0 != r.extra.end() && p0->is_number() ? fmt_number(p0->get<double>()) : "");
      cells.push_back(fmt::format("{:.6g}", r.design_seconds));
      cells.push_back(r.status);
      const auto eq28 =
          r.extra.find("predicted_mse_paper_eq28_erroneous");  // jump only (results/README.md)
      cells.push_back(eq28 != r.extra.end() && eq28->is_number() ? precise(eq28->get<double>())
                                                                 : "");
      for (std::size_t i = 0; i < cells.size(); ++i) out += (i ? "," : "") + csv_field(cells[i]);
      out += "\n";
    }
  }
  return out;
}

std::string transmissions_csv(const std::vector<SweepAxis>& sweeps,
                              const std::vector<std::vector<std::string>>& labels,
                              const std::vector<const Scenario*>& scenarios,
                              const std::vector<const CampaignResult*>& results) {
  std::string out;
  for (const auto& s : sweeps) out += csv_field(s.key) + ",";
  out += "sensor,output,policy,delta,samples_taken,samples_sent,sent_ratio,virtual_noise_rms\n";
  for (std::size_t c = 0; c < scenarios.size(); ++c) {
    const Scenario& sc = *scenarios[c];
    const CampaignResult& res = *results[c];
    for (std::size_t s = 0; s < sc.model.sensors.size(); ++s) {
      const auto& spec = sc.model.sensors[s].spec;
      std::int64_t taken = 0, sent = 0;
      std::vector<double> sse(static_cast<std::size_t>(spec.ny()), 0.0);
      for (const auto& run : res.runs) {
        if (run.empty()) continue;
        taken += run[0].sensor_taken[s];
        sent += run[0].sensor_sent[s];
        for (std::size_t i = 0; i < sse.size(); ++i) sse[i] += run[0].sensor_virtual_sse[s][i];
      }
      const Eigen::VectorXd* delta = spec.deadband();
      for (Eigen::Index i = 0; i < spec.ny(); ++i) {
        for (const auto& l : labels[c]) out += csv_field(l) + ",";
        out += fmt::format("{},{},{},{},{},{},{},{}\n", csv_field(spec.name), i + 1,
                           csv_field(spec.policy->name()),
                           delta != nullptr ? fmt::format("{:.6g}", (*delta)(i)) : "", taken, sent,
                           fmt_number(taken > 0 ? std::optional<double>(static_cast<double>(sent) /
                                                                        static_cast<double>(taken))
                                                : std::nullopt),
                           fmt_number(taken > 0 ? std::optional<double>(
                                                      std::sqrt(sse[static_cast<std::size_t>(i)] /
                                                                static_cast<double>(taken)))
                                                : std::nullopt));
      }
    }
  }
  return out;
}

std::string trajectory_csv(const Scenario& sc, const std::vector<TraceRow>& trace) {
  const Eigen::Index n = sc.model.plant.n();
  std::string out = "period";
  for (Eigen::Index i = 0; i < n; ++i) out += fmt::format(",x{}", i + 1);
  for (const auto& e : sc.estimators) {
    for (Eigen::Index i = 0; i < n; ++i)
      out += "," + csv_field(fmt::format("{}:xhat{}", e.name, i + 1));
  }
  for (const auto& s : sc.model.sensors)
    out += "," + csv_field(fmt::format("arrived:{}", s.spec.name));
  for (Eigen::Index j = 0; j < sc.model.plant.nu(); ++j) out += fmt::format(",u{}", j + 1);
  for (const auto& s : sc.model.sensors) {
    for (Eigen::Index i = 0; i < s.spec.ny(); ++i) {
      out += "," + csv_field(s.spec.ny() == 1 ? fmt::format("y:{}", s.spec.name)
                                              : fmt::format("y:{}:{}", s.spec.name, i + 1));
    }
  }
  const bool has_reference = sc.input.controller->sees_outputs();
  if (has_reference) out += ",reference";
  const bool modes = sc.model.mode_count() > 0;
  if (modes) {
    out += ",mode";
    for (const auto& e : sc.estimators) out += "," + csv_field(fmt::format("{}:mode", e.name));
  }
  const auto offsets =
      recentring_offsets(sc, trace);  // re-centred runs: the physical state (sim/run/physical.h)
  if (sc.recentre) {
    for (Eigen::Index i = 0; i < n; ++i) out += fmt::format(",x{}_physical", i + 1);
  }
  out += "\n";
  for (std::size_t t = 0; t < trace.size(); ++t) {
    const auto& r = trace[t];
    out += std::to_string(r.period);
    for (double v : r.x) out += fmt::format(",{:.9g}", v);
    for (const auto& xh : r.xhat) {
      for (double v : xh) out += fmt::format(",{:.9g}", v);
    }
    for (int a : r.arrivals) out += fmt::format(",{}", a);
    for (double v : r.u) out += fmt::format(",{:.9g}", v);
    for (double v : r.y) out += fmt::format(",{:.9g}", v);
    if (has_reference) out += "," + fmt_number(r.reference);
    if (modes) {
      out += r.mode >= 0 ? fmt::format(",{}", r.mode) : ",";
      for (int m : r.mode_hat) out += m >= 0 ? fmt::format(",{}", m) : ",";
    }
    if (sc.recentre) {
      for (Eigen::Index i = 0; i < n; ++i) {
        out += offsets[t] ? fmt::format(",{:.9g}", r.x[static_cast<std::size_t>(i)] +
                                                       (*offsets[t])[static_cast<std::size_t>(i)])
                          : ",";
      }
    }
    out += "\n";
  }
  return out;
}

}  // namespace ncosim::sim
