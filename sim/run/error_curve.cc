// sim/run/error_curve.cc — the run-averaged error against time: merging, statistics, storage.
#include "sim/run/error_curve.h"

#include <fmt/format.h>

#include <bit>
#include <boost/math/distributions/students_t.hpp>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <utility>

#include "kernel/wire.h"
#include "sim/files/csv.h"

namespace ncosim::sim {

namespace {

constexpr std::uint64_t kCurveFormat = 1;

using kernel::put_u64;

std::uint64_t get_u64(const std::string& in, std::size_t& pos) {
  return kernel::get_u64(in, pos, "error curve");
}

}  // namespace

ErrorCurve::ErrorCurve(std::int64_t periods, std::size_t estimators, Eigen::Index n)
    : periods_(periods), estimators_(estimators), n_(n) {
  const std::size_t cells =
      static_cast<std::size_t>(periods) * estimators * static_cast<std::size_t>(n + 1);
  sums_.assign(2 * cells, 0.0);
}

void ErrorCurve::merge(ErrorCurve&& other) {
  if (empty()) {
    *this = std::move(other);
    return;
  }
  merge(static_cast<const ErrorCurve&>(other));
}

void ErrorCurve::merge(const ErrorCurve& other) {
  if (other.empty()) return;
  if (empty()) {
    *this = other;
    return;
  }
  if (other.periods_ != periods_ || other.estimators_ != estimators_ || other.n_ != n_) {
    throw std::runtime_error("error curve: merging curves of different shapes");
  }
  for (std::size_t c = 0; c < sums_.size(); c += 2) {  // (hi, lo) + (hi', lo'): TwoSum of the his
    sums_[c + 1] += other.sums_[c + 1];
    add_to(sums_[c], sums_[c + 1], other.sums_[c]);
  }
  runs_.insert(runs_.end(), other.runs_.begin(), other.runs_.end());
}

double ErrorCurve::mean(std::int64_t k, std::size_t e) const {
  double total = 0.0;
  for (Eigen::Index i = 0; i < n_; ++i) total += value(cell(k, e, i));
  return total / static_cast<double>(runs_.size());
}

double ErrorCurve::mean_state(std::int64_t k, std::size_t e, Eigen::Index i) const {
  return value(cell(k, e, i)) / static_cast<double>(runs_.size());
}

double ErrorCurve::ci95(std::int64_t k, std::size_t e) const {
  const auto runs = static_cast<double>(runs_.size());
  if (runs_.size() < 2) return std::numeric_limits<double>::quiet_NaN();
  const double m = mean(k, e);
  const double s2 = value(cell(k, e, n_));
  double var = (s2 - runs * m * m) / (runs - 1.0);
  if (!std::isfinite(m) || !std::isfinite(var)) return std::numeric_limits<double>::quiet_NaN();
  // S2 - R m^2 cancels when every run has the same error (k = 0 from an exact start): what is
  // left below a few roundings of S2 is rounding, not spread.
  if (std::abs(var) * (runs - 1.0) <= 8.0 * std::numeric_limits<double>::epsilon() * s2) var = 0.0;
  if (t_runs_ != runs_.size()) {  // one quantile for every cell: the runs are the same
    t_runs_ = runs_.size();
    t975_ =
        boost::math::quantile(boost::math::complement(boost::math::students_t(runs - 1.0), 0.025));
  }
  return t975_ * std::sqrt(std::max(0.0, var) / runs);
}

std::string ErrorCurve::serialize() const {
  std::string out;
  out.reserve(8 * (5 + sums_.size() + runs_.size()));
  put_u64(out, kCurveFormat);
  put_u64(out, static_cast<std::uint64_t>(periods_));
  put_u64(out, estimators_);
  put_u64(out, static_cast<std::uint64_t>(n_));
  put_u64(out, runs_.size());
  for (auto r : runs_) put_u64(out, r);
  for (double v : sums_) put_u64(out, std::bit_cast<std::uint64_t>(v));
  return out;
}

ErrorCurve ErrorCurve::deserialize(const std::string& blob) {
  std::size_t pos = 0;
  if (get_u64(blob, pos) != kCurveFormat)
    throw std::runtime_error("error curve: unknown record format");
  const std::uint64_t periods = get_u64(blob, pos), estimators = get_u64(blob, pos),
                      n = get_u64(blob, pos);
  const std::uint64_t runs = get_u64(blob, pos);
  const std::uint64_t words = blob.size() / 8;
  // Every count is checked against the blob's size before anything is allocated.
  if (periods == 0 || estimators == 0 || n == 0 || periods > words || estimators > words ||
      n > words || runs > words || periods * estimators > words ||
      periods * estimators * (n + 1) > words / 2 ||
      blob.size() != 8 * (5 + runs + 2 * periods * estimators * (n + 1))) {
    throw std::runtime_error("error curve: corrupt record (sizes)");
  }
  ErrorCurve c(static_cast<std::int64_t>(periods), estimators, static_cast<Eigen::Index>(n));
  c.runs_.resize(runs);
  for (auto& r : c.runs_) r = get_u64(blob, pos);
  for (double& v : c.sums_) v = std::bit_cast<double>(get_u64(blob, pos));
  return c;
}

std::string error_curve_csv(const std::vector<SweepAxis>& sweeps,
                            const std::vector<std::vector<std::string>>& labels,
                            const std::vector<const Scenario*>& scenarios,
                            const std::vector<ErrorCurve>& curves) {
  fmt::memory_buffer out;
  for (const auto& s : sweeps) fmt::format_to(std::back_inserter(out), "{},", csv_field(s.key));
  const Eigen::Index n = scenarios.empty() ? 0 : scenarios.front()->model.plant.n();
  fmt::format_to(std::back_inserter(out), "estimator,period,time,runs,mse,mse_ci95");
  for (Eigen::Index i = 0; i < n; ++i) fmt::format_to(std::back_inserter(out), ",mse_x{}", i + 1);
  out.push_back('\n');
  for (std::size_t c = 0; c < scenarios.size() && c < curves.size(); ++c) {
    const Scenario& sc = *scenarios[c];
    const ErrorCurve& curve = curves[c];
    if (curve.empty() || curve.runs().empty()) continue;
    std::string prefix;
    for (const auto& l : labels[c]) prefix += csv_field(l) + ",";
    for (std::size_t e = 0; e < sc.estimators.size(); ++e) {
      const std::string name = csv_field(sc.estimators[e].name);
      for (std::int64_t k = 0; k < curve.periods(); ++k) {
        fmt::format_to(std::back_inserter(out), "{}{},{},{},{},{},{}", prefix, name, k,
                       fmt_number(static_cast<double>(k) * sc.run.period), curve.runs().size(),
                       fmt_number(curve.mean(k, e)), fmt_number(curve.ci95(k, e)));
        for (Eigen::Index i = 0; i < n; ++i)
          fmt::format_to(std::back_inserter(out), ",{}", fmt_number(curve.mean_state(k, e, i)));
        out.push_back('\n');
      }
    }
  }
  return fmt::to_string(out);
}

}  // namespace ncosim::sim
