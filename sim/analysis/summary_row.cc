// sim/analysis/summary_row.cc — see sim/analysis/summary_row.h.
#include "sim/analysis/summary_row.h"

#include <fmt/format.h>

namespace ncosim::sim {

std::string status_text(const SummaryRow& r) {
  if (r.expected_status.empty()) return r.status;
  if (status_as_expected(r.status, r.expected_status))
    return r.status == "ok" ? r.status : r.status + " (expected)";
  return fmt::format("{} (expected {})", r.status, r.expected_status);
}

std::string consistency_notes(const std::vector<SweepAxis>& sweeps,
                              const std::vector<SummaryRow>& rows) {
  std::string out;
  auto stat = [](const char* name, const std::optional<ConsistencyStat>& s) {
    return s ? consistency_stat_text(name, *s) : std::string();
  };
  for (const auto& r : rows) {
    if (r.consistency.empty() || r.consistency == "ok") continue;
    std::string where;
    for (std::size_t i = 0; i < r.sweep_labels.size() && i < sweeps.size(); ++i) {
      where += fmt::format("{} = {}, ", sweeps[i].key, r.sweep_labels[i]);
    }
    std::string stats = stat("NEES", r.nees);
    if (r.nis) stats += (stats.empty() ? "" : ", ") + stat("NIS", r.nis);
    out += fmt::format("- {}\"{}\": {} ({}).\n", where, r.estimator, r.consistency, stats);
  }
  if (out.empty()) return out;
  // A 95 % test: a consistent filter falls outside its bounds one time in twenty, so the header
  // says so rather than calling every flag a fault.
  return "\nFilter consistency (average NEES and NIS against two-sided 95 % chi-square bounds, "
         "which a\n"
         "consistent filter misses 1 time in 20; summary.csv nees.. columns):\n" +
         out;
}

}  // namespace ncosim::sim
