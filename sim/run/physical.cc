// sim/run/physical.cc — the offset that re-centring removed, added back for trajectory.csv.
#include "sim/run/physical.h"

#include <cmath>

namespace ncosim::sim {

std::vector<std::optional<std::vector<double>>> recentring_offsets(
    const Scenario& sc, const std::vector<TraceRow>& trace) {
  std::vector<std::optional<std::vector<double>>> out;
  if (!sc.recentre || trace.empty()) return out;
  const auto& plant = sc.model.plant;
  const Eigen::Index n = plant.n();
  std::vector<long double> o(static_cast<std::size_t>(n), 0.0L), next(o.size());
  bool lost = false;
  out.reserve(trace.size());
  for (std::size_t r = 0; r < trace.size(); ++r) {
    const TraceRow& row = trace[r];
    if (r > 0 && !lost) {
      const TraceRow& prev = trace[r - 1];
      const Eigen::MatrixXd& Am =
          (row.mode >= 0 && static_cast<std::size_t>(row.mode) < plant.modes.size())
              ? plant.modes[row.mode].A
              : plant.A;
      for (Eigen::Index i = 0; i < n; ++i) {
        long double s = 0.0L;
        for (Eigen::Index j = 0; j < n; ++j) {
          s += static_cast<long double>(Am(i, j)) * o[static_cast<std::size_t>(j)] +
               static_cast<long double>(plant.A(i, j)) *
                   static_cast<long double>(prev.x[static_cast<std::size_t>(j)]);
        }
        next[static_cast<std::size_t>(i)] = s;
      }
      o.swap(next);
    }
    if (!lost) {
      for (Eigen::Index i = 0; i < n; ++i) {
        const long double xp = static_cast<long double>(row.x[static_cast<std::size_t>(i)]) +
                               o[static_cast<std::size_t>(i)];
        if (!(std::fabs(static_cast<double>(xp)) <= kPhysicalLimit)) lost = true;
      }
    }
    if (lost) {
      out.emplace_back(std::nullopt);
      continue;
    }
    std::vector<double> v(o.size());
    for (std::size_t i = 0; i < o.size(); ++i) v[i] = static_cast<double>(o[i]);
    out.emplace_back(std::move(v));
  }
  return out;
}

}  // namespace ncosim::sim
