// sim/analysis/consistency.cc — NEES and NIS averages against their chi-square bounds.
#include "sim/analysis/consistency.h"

#include <fmt/format.h>

#include <boost/math/distributions/chi_squared.hpp>
#include <cstdlib>

namespace ncosim::sim {

namespace {

// The two-sided 95 % bounds of the average of `count` terms whose sum is chi2(dof) for a
// consistent filter: the 2.5 % and 97.5 % quantiles of chi2(dof), divided by `count`.
ConsistencyStat bounded(double mean, double count, double dof) {
  const boost::math::chi_squared dist(dof);
  return ConsistencyStat{mean, boost::math::quantile(dist, 0.025) / count,
                         boost::math::quantile(boost::math::complement(dist, 0.025)) / count};
}

std::string side(const char* name, const ConsistencyStat& s) {
  if (s.mean > s.hi) {
    return std::string(name) + " above its 95 % bound: the covariance is too small (overconfident)";
  }
  return std::string(name) + " below its 95 % bound: the covariance is too large (pessimistic)";
}

}  // namespace

std::optional<ConsistencyStat> nees_stat(const ConsistencySums& s, std::int64_t n) {
  if (s.nees_count <= 0 || s.nees_runs <= 0 || n <= 0) return std::nullopt;
  const double runs = static_cast<double>(s.nees_runs);
  return bounded(s.nees / static_cast<double>(s.nees_count), runs, runs * static_cast<double>(n));
}

std::optional<ConsistencyStat> nis_stat(const ConsistencySums& s) {
  if (s.nis_count <= 0 || s.nis_dof <= 0) return std::nullopt;
  const auto updates = static_cast<double>(s.nis_count);
  return bounded(s.nis / updates, updates, static_cast<double>(s.nis_dof));
}

std::string consistency_stat_text(const std::string& name, const ConsistencyStat& s) {
  const int where = s.mean > s.hi ? 1 : s.mean >= s.lo ? 0 : -1;
  // -1, 0, 1 as a < b, a == b, a > b (a NaN compares as neither).
  auto order = [](double a, double b) { return a < b ? -1 : a > b ? 1 : 0; };
  std::string mean, lo, hi;
  for (int digits = 4; digits <= 17; ++digits) {
    mean = fmt::format("{:#.{}g}", s.mean, digits);
    lo = fmt::format("{:#.{}g}", s.lo, digits);
    hi = fmt::format("{:#.{}g}", s.hi, digits);
    const double m = std::strtod(mean.c_str(), nullptr), l = std::strtod(lo.c_str(), nullptr),
                 h = std::strtod(hi.c_str(), nullptr);
    if (order(m, l) == order(s.mean, s.lo) && order(m, h) == order(s.mean, s.hi)) break;
  }
  return fmt::format("{} {} {} [{}, {}]", name, mean,
                     where > 0   ? "above"
                     : where < 0 ? "below"
                                 : "in",
                     lo, hi);
}

std::string consistency_note(const std::optional<ConsistencyStat>& nees,
                             const std::optional<ConsistencyStat>& nis) {
  if (!nees && !nis) return "";
  std::string out;
  if (nees && !nees->inside()) out = side("NEES", *nees);
  if (nis && !nis->inside()) out += (out.empty() ? "" : "; ") + side("NIS", *nis);
  return out.empty() ? "ok" : out;
}

}  // namespace ncosim::sim
