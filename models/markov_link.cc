// models/markov_link.cc — the Markov-chain link kinds of models/link.h (MarkovLink,
// Gilbert–Elliott) and the stationary law of a chain.
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstddef>

#include "kernel/check.h"
#include "models/link.h"
#include "models/link_util.h"
#include "models/plant.h"  // stationary_law

namespace ncosim::models {

using namespace link_util;  // NOLINT(google-build-using-namespace): the links' own helpers

// ---------------------------------------------------------------------------------------
// MarkovLink

// Solves pi' T = pi', sum(pi) = 1 as the stacked least-squares system
// [T' - I; 1'] pi = [0; 1]. For an irreducible chain the system has full column rank and
// the solution is exact; for a reducible one the minimum-norm solution weights the
// stationary laws of the closed classes by 1/|pi_c|^2, so it is still a stationary law.
Eigen::VectorXd stationary_law(const Eigen::MatrixXd& transition) {
  const Eigen::Index n = transition.rows();
  Eigen::MatrixXd m(n + 1, n);
  m.topRows(n) = transition.transpose() - Eigen::MatrixXd::Identity(n, n);
  m.row(n).setOnes();
  Eigen::VectorXd rhs = Eigen::VectorXd::Zero(n + 1);
  rhs(n) = 1.0;
  Eigen::VectorXd pi = m.completeOrthogonalDecomposition().solve(rhs);
  for (Eigen::Index i = 0; i < n; ++i) {
    NCOSIM_CHECK(pi(i) > -1e-9);
    pi(i) = std::max(pi(i), 0.0);
  }
  pi /= pi.sum();
  NCOSIM_CHECK((transition.transpose() * pi - pi).cwiseAbs().maxCoeff() < 1e-9);
  return pi;
}

MarkovLink::MarkovLink(Eigen::MatrixXd transition, std::vector<double> loss,
                       std::vector<std::vector<double>> delay_pmf, std::vector<double> initial,
                       Step step)
    : transition_(std::move(transition)),
      loss_(std::move(loss)),
      delay_pmf_(std::move(delay_pmf)),
      initial_(std::move(initial)),
      step_(step) {
  NCOSIM_CHECK(step_ == Step::kPacket || step_ == Step::kPeriod);
  const Eigen::Index n = transition_.rows();
  const auto un = static_cast<std::size_t>(n);
  NCOSIM_CHECK(n >= 1 && transition_.cols() == n);
  NCOSIM_CHECK(loss_.size() == un);
  NCOSIM_CHECK(delay_pmf_.empty() || delay_pmf_.size() == un);
  NCOSIM_CHECK(initial_.empty() || initial_.size() == un);

  transition_cdf_.reserve(un * un);
  for (Eigen::Index i = 0; i < n; ++i) {
    std::vector<double> row(un);
    for (Eigen::Index j = 0; j < n; ++j) {
      row[static_cast<std::size_t>(j)] = transition_(i, j);
      NCOSIM_CHECK(is_probability(transition_(i, j)));
    }
    NCOSIM_CHECK(std::abs(sum(row) - 1.0) <= kSumTolerance);
    const std::vector<double> c = cumulative_law(row);
    transition_cdf_.insert(transition_cdf_.end(), c.begin(), c.end());
  }
  for (const double l : loss_) NCOSIM_CHECK(is_probability(l));
  delay_cdf_.resize(un);
  for (std::size_t s = 0; s < delay_pmf_.size(); ++s) {
    for (const double p : delay_pmf_[s]) NCOSIM_CHECK(is_probability(p));
    NCOSIM_CHECK(sum(delay_pmf_[s]) <= 1.0 + kSumTolerance);
    delay_cdf_[s] = cumulative(delay_pmf_[s]);
  }

  stationary_ = stationary_law(transition_);
  if (initial_.empty()) {
    initial_cdf_ = cumulative_law(std::vector<double>(stationary_.data(), stationary_.data() + n));
  } else {
    for (const double p : initial_) NCOSIM_CHECK(is_probability(p));
    NCOSIM_CHECK(std::abs(sum(initial_) - 1.0) <= kSumTolerance);
    initial_cdf_ = cumulative_law(initial_);
  }
}

std::unique_ptr<Link> MarkovLink::clone() const {
  auto copy = std::make_unique<MarkovLink>(*this);
  copy->state_ = 0;
  copy->period_ = 0;
  return copy;
}

void MarkovLink::reset(kernel::Rng& rng) {
  state_ = static_cast<int>(
      sample(initial_cdf_.data(), initial_cdf_.data() + initial_cdf_.size(), uniform(rng)));
  period_ = 0;
}

void MarkovLink::advance(std::int64_t period, kernel::Rng& rng) {
  if (step_ != Step::kPeriod) return;
  const std::size_t n = loss_.size();
  for (; period_ < period; ++period_) {
    const double* row = transition_cdf_.data() + static_cast<std::size_t>(state_) * n;
    state_ = static_cast<int>(sample(row, row + n, uniform(rng)));
  }
}

std::int64_t MarkovLink::transmit(kernel::Rng& rng) {
  const auto s = static_cast<std::size_t>(state_);
  std::int64_t delay = kLost;
  if (uniform(rng) >= loss_[s]) {
    const std::vector<double>& c = delay_cdf_[s];
    if (c.empty()) {
      delay = 0;
    } else {
      // A per-state pmf summing to less than 1 loses the rest, as DelayPmfLink does.
      const std::size_t d = sample(c.data(), c.data() + c.size(), uniform(rng));
      if (d < c.size()) delay = static_cast<std::int64_t>(d);
    }
  }
  if (step_ == Step::kPacket) {
    const std::size_t n = loss_.size();
    const double* row = transition_cdf_.data() + s * n;
    state_ = static_cast<int>(sample(row, row + n, uniform(rng)));
  }
  return delay;
}

std::vector<double> MarkovLink::delay_pmf(int max_delay) const {
  check_max_delay(max_delay);
  std::vector<double> out(static_cast<std::size_t>(max_delay) + 1, 0.0);
  for (std::size_t s = 0; s < loss_.size(); ++s) {
    const double delivered = stationary_(static_cast<Eigen::Index>(s)) * (1.0 - loss_[s]);
    if (delay_pmf_.empty() || delay_pmf_[s].empty()) {
      out[0] += delivered;
    } else {
      for (std::size_t d = 0; d < out.size() && d < delay_pmf_[s].size(); ++d) {
        out[d] += delivered * delay_pmf_[s][d];
      }
    }
  }
  return out;
}

double MarkovLink::loss_probability() const {
  double lost = 0.0;
  for (std::size_t s = 0; s < loss_.size(); ++s) {
    const double mass =
        delay_pmf_.empty() || delay_pmf_[s].empty() ? 1.0 : std::min(1.0, sum(delay_pmf_[s]));
    lost += stationary_(static_cast<Eigen::Index>(s)) * (1.0 - (1.0 - loss_[s]) * mass);
  }
  return lost;
}

// Pair law under the stationary chain: e_s = P(on time | state s),
// P(a[k-1] = 1, a[k] = 1) = sum_s pi_s e_s sum_t T(s, t) e_t, P(a = 1) = sum_s pi_s e_s.
Eigen::Matrix2d MarkovLink::on_time_chain() const {
  const Eigen::Index n = transition_.rows();
  Eigen::VectorXd e(n);
  for (Eigen::Index s = 0; s < n; ++s) {
    const auto us = static_cast<std::size_t>(s);
    const double d0 = delay_pmf_.empty() || delay_pmf_[us].empty() ? 1.0 : delay_pmf_[us][0];
    e(s) = (1.0 - loss_[us]) * d0;
  }
  const double p = stationary_.dot(e);
  const double pdd = stationary_.cwiseProduct(e).dot(transition_ * e);
  Eigen::Matrix2d m;
  const double d_after_d = p > 0.0 ? std::clamp(pdd / p, 0.0, 1.0) : 0.0;
  const double d_after_l = p < 1.0 ? std::clamp((p - pdd) / (1.0 - p), 0.0, 1.0) : 1.0;
  m << d_after_d, 1.0 - d_after_d, d_after_l, 1.0 - d_after_l;
  return m;
}

std::vector<double> MarkovLink::state_law() const {
  return {stationary_.data(), stationary_.data() + stationary_.size()};
}

std::optional<double> MarkovLink::mean_loss_burst(std::optional<int> gap) const {
  if (!gap) return std::nullopt;
  NCOSIM_CHECK(*gap >= 1);
  const Eigen::Index n = transition_.rows();
  Eigen::VectorXd lost(n);
  for (Eigen::Index s = 0; s < n; ++s) {
    const auto us = static_cast<std::size_t>(s);
    const double mass =
        delay_pmf_.empty() || delay_pmf_[us].empty() ? 1.0 : std::min(1.0, sum(delay_pmf_[us]));
    lost(s) = 1.0 - (1.0 - loss_[us]) * mass;
  }
  Eigen::MatrixXd step = Eigen::MatrixXd::Identity(n, n);
  for (int i = 0; i < *gap; ++i) step = step * transition_;
  const double pl = stationary_.dot(lost);
  const double pll = stationary_.cwiseProduct(lost).dot(step * lost);
  if (!(pl - pll > 1e-300)) return std::nullopt;  // the losses never end
  return pl / (pl - pll);
}

std::unique_ptr<MarkovLink> make_gilbert_elliott(double p_good_to_bad, double p_bad_to_good,
                                                 double loss_good, double loss_bad,
                                                 MarkovLink::Step step) {
  NCOSIM_CHECK(is_probability(p_good_to_bad) && is_probability(p_bad_to_good));
  Eigen::MatrixXd t(2, 2);
  t << 1.0 - p_good_to_bad, p_good_to_bad, p_bad_to_good, 1.0 - p_bad_to_good;
  return std::make_unique<MarkovLink>(std::move(t), std::vector<double>{loss_good, loss_bad},
                                      std::vector<std::vector<double>>{}, std::vector<double>{},
                                      step);
}

GilbertElliottByMean gilbert_elliott_by_mean(double mean_loss, double mean_burst, double loss_good,
                                             double loss_bad) {
  GilbertElliottByMean out;
  const auto fail = [&](const char* key, std::string why) {
    out.error_key = key;
    out.error = std::move(why);
    return out;
  };
  const double P = mean_loss, b = mean_burst, lg = loss_good, lb = loss_bad;
  if (!(lg < lb)) {
    return fail(
        "loss_bad",
        fmt::format("expected loss_good < loss_bad with mean_loss and mean_burst, got {} >= {}", lg,
                    lb));
  }
  if (!(P > lg && P < lb)) {
    return fail(
        "mean_loss",
        fmt::format("expected loss_good < mean_loss < loss_bad, got mean_loss = {} ({} < {} < {} "
                    "fails)",
                    P, lg, P, lb));
  }
  if (!(std::isfinite(b) && b >= 1.0))
    return fail("mean_burst", fmt::format("expected a finite mean burst length >= 1, got {}", b));
  const double pi_b = (P - lg) / (lb - lg);
  const double v = pi_b * (1.0 - pi_b) * (lb - lg) * (lb - lg);
  const double lambda = P * (1.0 - P - 1.0 / b) / v;
  // lambda < 1 (a chain that moves) and p_gb, p_bg <= 1: lambda >= 1 - 1 / max(pi_B, pi_G).
  const double lambda_min = 1.0 - 1.0 / std::max(pi_b, 1.0 - pi_b);
  // The burst lengths that these bounds allow: b = P / (P (1 - P) - lambda V).
  const auto burst_at = [&](double l) { return P / (P * (1.0 - P) - l * v); };
  if (!(lambda < 1.0)) {
    return fail(
        "mean_burst",
        fmt::format("expected mean_burst < {} (the longest mean burst these loss_good, loss_bad "
                    "and mean_loss allow), got {}",
                    burst_at(1.0), b));
  }
  if (lambda < lambda_min) {
    return fail("mean_burst",
                fmt::format("expected mean_burst >= {} (the shortest mean burst these loss_good, "
                            "loss_bad and mean_loss allow), got {}",
                            burst_at(lambda_min), b));
  }
  out.p_good_to_bad = std::clamp(pi_b * (1.0 - lambda), 0.0, 1.0);
  out.p_bad_to_good = std::clamp((1.0 - pi_b) * (1.0 - lambda), 0.0, 1.0);
  return out;
}

}  // namespace ncosim::models
