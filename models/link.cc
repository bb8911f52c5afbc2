// models/link.cc — the memoryless link kinds of models/link.h (each packet's fate drawn afresh
// from one law) and what every link shares. The Markov kinds are in markov_link.cc, the
// replayed trace in trace_link.cc.
#include "models/link.h"

#include <algorithm>
#include <boost/math/distributions/negative_binomial.hpp>
#include <boost/random/negative_binomial_distribution.hpp>
#include <cmath>
#include <cstddef>

#include "kernel/check.h"
#include "models/link_util.h"

namespace ncosim::models {

using namespace link_util;  // NOLINT(google-build-using-namespace): this file's own helpers

// ---------------------------------------------------------------------------------------
// DelayPmfLink

DelayPmfLink::DelayPmfLink(std::vector<double> pmf, bool independent)
    : pmf_(std::move(pmf)), cdf_(cumulative(pmf_)), independent_(independent) {
  for (const double p : pmf_) NCOSIM_CHECK(is_probability(p));
  if (!independent_) NCOSIM_CHECK(sum(pmf_) <= 1.0 + kSumTolerance);
}

std::unique_ptr<Link> DelayPmfLink::clone() const { return std::make_unique<DelayPmfLink>(*this); }

std::int64_t DelayPmfLink::transmit(kernel::Rng& rng) {
  if (independent_) {
    // The packet's first delivered copy: draw every copy (the same draws as
    // transmit_copies) and keep the smallest delivered delay.
    std::int64_t first = kLost;
    for (std::size_t d = 0; d < pmf_.size(); ++d) {
      if (uniform(rng) < pmf_[d] && first == kLost) first = static_cast<std::int64_t>(d);
    }
    return first;
  }
  const std::size_t d = sample(cdf_.data(), cdf_.data() + cdf_.size(), uniform(rng));
  return d < cdf_.size() ? static_cast<std::int64_t>(d) : kLost;
}

void DelayPmfLink::transmit_copies(kernel::Rng& rng, std::vector<std::int64_t>& delays) {
  if (!independent_) {
    Link::transmit_copies(rng, delays);
    return;
  }
  delays.clear();
  for (std::size_t d = 0; d < pmf_.size(); ++d) {
    if (uniform(rng) < pmf_[d]) delays.push_back(static_cast<std::int64_t>(d));
  }
}

std::vector<double> DelayPmfLink::delay_pmf(int max_delay) const {
  check_max_delay(max_delay);
  std::vector<double> out(static_cast<std::size_t>(max_delay) + 1, 0.0);
  for (std::size_t d = 0; d < out.size() && d < pmf_.size(); ++d) out[d] = pmf_[d];
  return out;
}

double DelayPmfLink::loss_probability() const {
  if (independent_) {
    double none = 1.0;
    for (const double p : pmf_) none *= 1.0 - p;
    return none;
  }
  return std::max(0.0, 1.0 - sum(pmf_));
}

// ---------------------------------------------------------------------------------------
// BernoulliLink

BernoulliLink::BernoulliLink(double loss, std::int64_t delay) : loss_(loss), delay_(delay) {
  NCOSIM_CHECK(is_probability(loss_));
  NCOSIM_CHECK(delay_ >= 0);
}

std::unique_ptr<Link> BernoulliLink::clone() const {
  return std::make_unique<BernoulliLink>(*this);
}

std::int64_t BernoulliLink::transmit(kernel::Rng& rng) {
  return uniform(rng) < loss_ ? kLost : delay_;
}

std::vector<double> BernoulliLink::delay_pmf(int max_delay) const {
  check_max_delay(max_delay);
  std::vector<double> out(static_cast<std::size_t>(max_delay) + 1, 0.0);
  if (delay_ <= max_delay) out[static_cast<std::size_t>(delay_)] = 1.0 - loss_;
  return out;
}

// ---------------------------------------------------------------------------------------
// NegativeBinomialLink

NegativeBinomialLink::NegativeBinomialLink(int successes, double p, double loss)
    : successes_(successes), p_(p), loss_(loss) {
  NCOSIM_CHECK(successes_ >= 1);
  NCOSIM_CHECK(std::isfinite(p_) && p_ > 0.0 && p_ <= 1.0);
  NCOSIM_CHECK(is_probability(loss_));
}

std::unique_ptr<Link> NegativeBinomialLink::clone() const {
  return std::make_unique<NegativeBinomialLink>(*this);
}

std::int64_t NegativeBinomialLink::transmit(kernel::Rng& rng) {
  if (uniform(rng) < loss_) return kLost;
  if (p_ == 1.0) return 0;  // every trial succeeds (Boost's gamma needs a positive scale)
  // Gamma–Poisson mixture; the distribution object holds only (r, p), no allocation.
  const boost::random::negative_binomial_distribution<std::int64_t, double> nb(successes_, p_);
  return nb(rng);
}

std::vector<double> NegativeBinomialLink::delay_pmf(int max_delay) const {
  check_max_delay(max_delay);
  std::vector<double> out(static_cast<std::size_t>(max_delay) + 1, 0.0);
  if (p_ == 1.0) {
    out[0] = 1.0 - loss_;
    return out;
  }
  const boost::math::negative_binomial_distribution<double> nb(successes_, p_);
  for (std::size_t d = 0; d < out.size(); ++d) {
    out[d] = (1.0 - loss_) * boost::math::pdf(nb, static_cast<double>(d));
  }
  return out;
}

// ---------------------------------------------------------------------------------------
// ArrivalCdfLink

ArrivalCdfLink::ArrivalCdfLink(std::vector<double> cdf, double tail)
    : cdf_(std::move(cdf)), tail_(tail) {
  NCOSIM_CHECK(is_probability(tail_));
  for (std::size_t h = 0; h < cdf_.size(); ++h) {
    NCOSIM_CHECK(is_probability(cdf_[h]));
    if (h > 0) NCOSIM_CHECK(cdf_[h] >= cdf_[h - 1]);
  }
  if (!cdf_.empty()) NCOSIM_CHECK(cdf_.back() <= tail_);
}

std::unique_ptr<Link> ArrivalCdfLink::clone() const {
  return std::make_unique<ArrivalCdfLink>(*this);
}

std::int64_t ArrivalCdfLink::transmit(kernel::Rng& rng) {
  // u < lambda_h  <=>  delay <= h, with lambda_h = tail for h >= cdf.size().
  const double u = uniform(rng);
  if (u >= tail_) return kLost;
  return static_cast<std::int64_t>(sample(cdf_.data(), cdf_.data() + cdf_.size(), u));
}

std::vector<double> ArrivalCdfLink::delay_pmf(int max_delay) const {
  check_max_delay(max_delay);
  const auto lambda = [this](std::size_t h) { return h < cdf_.size() ? cdf_[h] : tail_; };
  std::vector<double> out(static_cast<std::size_t>(max_delay) + 1, 0.0);
  for (std::size_t d = 0; d < out.size(); ++d) {
    out[d] = lambda(d) - (d == 0 ? 0.0 : lambda(d - 1));
  }
  return out;
}

std::optional<double> MemorylessLink::mean_loss_burst(std::optional<int> gap) const {
  (void)gap;
  return independent_loss_burst(loss_probability());
}

LinkReporting::LossModel loss_model_of(const Link& link) {
  const LinkReporting* r = link.reporting();
  return r != nullptr ? r->loss_model() : LinkReporting::LossModel::kCorrelated;
}

LinkReporting::StateStep state_step_of(const Link& link) {
  const LinkReporting* r = link.reporting();
  return r != nullptr ? r->state_step() : LinkReporting::StateStep::kNone;
}

int state_of(const Link& link) {
  const LinkReporting* r = link.reporting();
  return r != nullptr ? r->state() : -1;
}

std::vector<double> state_law_of(const Link& link) {
  const LinkReporting* r = link.reporting();
  return r != nullptr ? r->state_law() : std::vector<double>{};
}

std::optional<double> mean_loss_burst_of(const Link& link, std::optional<int> gap) {
  const LinkReporting* r = link.reporting();
  return r != nullptr ? r->mean_loss_burst(gap) : std::nullopt;
}

void bind_run(Link& link, const MobilityRun* mobility, std::uint64_t seed, std::uint64_t run) {
  if (RunBinding* b = link.run_binding()) b->bind_run(mobility, seed, run);
}

std::optional<double> independent_loss_burst(double p) {
  if (!(p < 1.0)) return std::nullopt;
  return 1.0 / (1.0 - p);
}

Eigen::Matrix2d Link::on_time_chain() const {
  const double p = delay_pmf(0)[0];
  Eigen::Matrix2d m;
  m << p, 1.0 - p, p, 1.0 - p;
  return m;
}

}  // namespace ncosim::models
