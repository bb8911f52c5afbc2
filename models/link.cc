// models/link.cc — the link kinds of models/link.h and the trace reader.
#include "models/link.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <boost/math/distributions/negative_binomial.hpp>
#include <boost/random/negative_binomial_distribution.hpp>
#include <boost/random/uniform_01.hpp>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstddef>
#include <cstring>
#include <fstream>
#include <string_view>

#include "config/config.h"  // escape_text
#include "kernel/check.h"
#include "models/plant.h"  // stationary_law

namespace ncosim::models {
namespace {

// Tolerance on "sums to 1" for laws given by the caller (rows of a transition matrix, ...).
constexpr double kSumTolerance = 1e-9;

double uniform(sim::Rng& rng) {
  boost::random::uniform_01<double> u;
  return u(rng);
}

bool is_probability(double p) { return std::isfinite(p) && p >= 0.0 && p <= 1.0; }

double sum(const std::vector<double>& v) {
  double s = 0.0;
  for (const double x : v) s += x;
  return s;
}

// Running sums of p: the sampler draws u ~ U[0, 1) and takes the first index whose
// cumulative value exceeds u; u beyond the last value means "none" (lost).
std::vector<double> cumulative(const std::vector<double>& p) {
  std::vector<double> c(p.size());
  double s = 0.0;
  for (std::size_t i = 0; i < p.size(); ++i) {
    s += p[i];
    c[i] = s;
  }
  return c;
}

// Cumulative law of a distribution that sums to 1 (within kSumTolerance): rounding must
// never leave a gap above the last value, so every entry from the last index with
// positive probability on is set to exactly 1.
std::vector<double> cumulative_law(const std::vector<double>& p) {
  std::vector<double> c = cumulative(p);
  std::size_t last = 0;
  for (std::size_t i = 0; i < p.size(); ++i) {
    if (p[i] > 0.0) last = i;
  }
  for (std::size_t i = last; i < c.size(); ++i) c[i] = 1.0;
  return c;
}

// Index of the first cumulative value > u in [first, last): last - first when none is.
std::size_t sample(const double* first, const double* last, double u) {
  return static_cast<std::size_t>(std::upper_bound(first, last, u) - first);
}

void check_max_delay(int max_delay) { NCOSIM_CHECK(max_delay >= 0); }

}  // namespace

// ---------------------------------------------------------------------------------------
// DelayPmfLink

DelayPmfLink::DelayPmfLink(std::vector<double> pmf, bool independent)
    : pmf_(std::move(pmf)), cdf_(cumulative(pmf_)), independent_(independent) {
  for (const double p : pmf_) NCOSIM_CHECK(is_probability(p));
  if (!independent_) NCOSIM_CHECK(sum(pmf_) <= 1.0 + kSumTolerance);
}

std::unique_ptr<Link> DelayPmfLink::clone() const { return std::make_unique<DelayPmfLink>(*this); }

std::int64_t DelayPmfLink::transmit(sim::Rng& rng) {
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

void DelayPmfLink::transmit_copies(sim::Rng& rng, std::vector<std::int64_t>& delays) {
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

std::int64_t BernoulliLink::transmit(sim::Rng& rng) {
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

std::int64_t NegativeBinomialLink::transmit(sim::Rng& rng) {
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

std::int64_t ArrivalCdfLink::transmit(sim::Rng& rng) {
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

std::optional<double> Link::mean_loss_burst(std::optional<int> gap) const {
  (void)gap;
  if (loss_model() == LossModel::kIndependent) return independent_loss_burst(loss_probability());
  return std::nullopt;
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

void MarkovLink::reset(sim::Rng& rng) {
  state_ = static_cast<int>(
      sample(initial_cdf_.data(), initial_cdf_.data() + initial_cdf_.size(), uniform(rng)));
  period_ = 0;
}

void MarkovLink::advance(std::int64_t period, sim::Rng& rng) {
  if (step_ != Step::kPeriod) return;
  const std::size_t n = loss_.size();
  for (; period_ < period; ++period_) {
    const double* row = transition_cdf_.data() + static_cast<std::size_t>(state_) * n;
    state_ = static_cast<int>(sample(row, row + n, uniform(rng)));
  }
}

std::int64_t MarkovLink::transmit(sim::Rng& rng) {
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

// ---------------------------------------------------------------------------------------
// TraceLink

TraceLink::TraceLink(std::vector<std::optional<std::int64_t>> delays, std::size_t segment)
    : delays_(std::move(delays)), segment_(segment) {
  for (const auto& d : delays_) NCOSIM_CHECK(!d || *d >= 0);
  NCOSIM_CHECK(segment_ <= delays_.size());
}

std::unique_ptr<Link> TraceLink::clone() const {
  auto copy = std::make_unique<TraceLink>(*this);
  copy->start_ = 0;
  copy->next_ = 0;
  return copy;
}

void TraceLink::bind_run(const MobilityRun* mobility, std::uint64_t seed, std::uint64_t run) {
  (void)mobility, (void)seed;
  start_ =
      segment_ > 0 ? static_cast<std::size_t>(run % (delays_.size() / segment_)) * segment_ : 0;
}

void TraceLink::reset(sim::Rng& rng) {
  (void)rng;
  next_ = start_;
}

std::int64_t TraceLink::transmit(sim::Rng& rng) {
  (void)rng;
  NCOSIM_CHECK(next_ < (segment_ > 0 ? start_ + segment_ : delays_.size()));
  const auto& d = delays_[next_++];
  return d ? *d : kLost;
}

std::vector<double> TraceLink::delay_pmf(int max_delay) const {
  check_max_delay(max_delay);
  std::vector<double> out(static_cast<std::size_t>(max_delay) + 1, 0.0);
  if (delays_.empty()) return out;
  for (const auto& d : delays_) {
    if (d && *d <= max_delay) out[static_cast<std::size_t>(*d)] += 1.0;
  }
  for (double& p : out) p /= static_cast<double>(delays_.size());
  return out;
}

double TraceLink::loss_probability() const {
  if (delays_.empty()) return 1.0;  // carries no packet: nothing is ever delivered
  const auto lost =
      std::count_if(delays_.begin(), delays_.end(), [](const auto& d) { return !d.has_value(); });
  return static_cast<double>(lost) / static_cast<double>(delays_.size());
}

std::optional<double> TraceLink::mean_loss_burst(std::optional<int> gap) const {
  if (!gap) return std::nullopt;
  std::int64_t runs = 0, lost = 0;
  bool in_run = false;
  for (const auto& d : delays_) {
    if (!d) {
      ++lost;
      if (!in_run) ++runs;
    }
    in_run = !d;
  }
  if (runs == 0) return std::nullopt;
  return static_cast<double>(lost) / static_cast<double>(runs);
}

// ---------------------------------------------------------------------------------------
// load_trace

namespace {

std::string_view trim(std::string_view s) {
  const auto blank = [](char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\n'; };
  while (!s.empty() && blank(s.front())) s.remove_prefix(1);
  while (!s.empty() && blank(s.back())) s.remove_suffix(1);
  return s;
}

// A whole field holding a non-negative decimal integer (no sign, no fraction).
std::optional<std::int64_t> parse_count(std::string_view field) {
  field = trim(field);
  if (field.empty()) return std::nullopt;
  std::int64_t value = 0;
  const auto [end, ec] = std::from_chars(field.data(), field.data() + field.size(), value);
  if (ec != std::errc() || end != field.data() + field.size() || value < 0) return std::nullopt;
  return value;
}

}  // namespace

namespace {

// Input limits of a trace (models/link.h load_trace; documented in scenarios/README.md).
constexpr std::int64_t kMaxTraceBytes = 1'000'000'000;
constexpr std::size_t kMaxTraceLineBytes = 4096;
constexpr std::int64_t kMaxTracePackets = 50'000'000;

// Lines of a regular file read through a bounded buffer (a line longer than the limit is an
// error at its line, never an allocation of the whole file).
class TraceReader {
 public:
  explicit TraceReader(const std::string& path) : path_(path) {
    fd_ =
        ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);  // a FIFO must not block the open
    if (fd_ < 0)
      throw TraceError(path, 0, "cannot open trace file '" + path + "': " + std::strerror(errno));
    struct stat st {};
    if (::fstat(fd_, &st) != 0 || !S_ISREG(st.st_mode)) {
      const char* what = S_ISFIFO(st.st_mode)   ? "a FIFO"
                         : S_ISCHR(st.st_mode)  ? "a character device"
                         : S_ISBLK(st.st_mode)  ? "a block device"
                         : S_ISDIR(st.st_mode)  ? "a folder"
                         : S_ISSOCK(st.st_mode) ? "a socket"
                                                : "not a regular file";
      ::close(fd_);
      fd_ = -1;
      throw TraceError(path, 0,
                       "expected a regular file, got " + std::string(what) + " '" + path + "'");
    }
    if (st.st_size > kMaxTraceBytes) {
      ::close(fd_);
      fd_ = -1;
      throw TraceError(path, 0,
                       "trace file '" + path + "' holds " + std::to_string(st.st_size) +
                           " bytes; at most " + std::to_string(kMaxTraceBytes) + " are read");
    }
    // O_NONBLOCK stays: a "regular" file that blocks on read (/proc/kmsg) is refused, not waited
    // on.
  }
  ~TraceReader() {
    if (fd_ >= 0) ::close(fd_);
  }
  TraceReader(const TraceReader&) = delete;
  TraceReader& operator=(const TraceReader&) = delete;

  // The next line (without its '\n') into `line`; false at the end of the file.
  bool next(std::string& line, int line_number) {
    line.clear();
    while (true) {
      if (pos_ == len_) {
        if (eof_) return !line.empty();
        const ssize_t n = ::read(fd_, buf_, sizeof buf_);
        if (n < 0) {
          if (errno == EINTR) continue;
          if (errno == EAGAIN || errno == EWOULDBLOCK) {
            throw TraceError(path_, 0,
                             "cannot read trace file '" + path_ +
                                 "' without waiting (a file whose content comes and goes, not a "
                                 "recorded trace)");
          }
          throw TraceError(path_, line_number,
                           "cannot read trace file '" + path_ + "': " + std::strerror(errno));
        }
        if (n == 0) {
          eof_ = true;
          return !line.empty();
        }
        pos_ = 0;
        len_ = static_cast<std::size_t>(n);
        total_ += n;
        if (total_ > kMaxTraceBytes) {
          throw TraceError(path_, line_number,
                           "trace file '" + path_ + "' grew beyond " +
                               std::to_string(kMaxTraceBytes) + " bytes while it was read");
        }
      }
      const char* start = buf_ + pos_;
      const void* nl = std::memchr(start, '\n', len_ - pos_);
      const std::size_t take =
          nl ? static_cast<std::size_t>(static_cast<const char*>(nl) - start) : len_ - pos_;
      if (line.size() + take > kMaxTraceLineBytes) {
        throw TraceError(path_, line_number,
                         "line longer than " + std::to_string(kMaxTraceLineBytes) + " bytes");
      }
      line.append(start, take);
      pos_ += take;
      if (nl) {
        ++pos_;
        return true;
      }
    }
  }

 private:
  std::string path_;
  int fd_ = -1;
  char buf_[65536];
  std::size_t pos_ = 0, len_ = 0;
  std::int64_t total_ = 0;
  bool eof_ = false;
};

}  // namespace

TraceError::TraceError(std::string f, int l, const std::string& what)
    : std::runtime_error(sim::escape_text(what)), file(std::move(f)), line(l) {}

std::vector<std::optional<std::int64_t>> load_trace(const std::string& path, int* first_row_line) {
  TraceReader in(path);
  if (first_row_line != nullptr) *first_row_line = 1;

  std::vector<std::optional<std::int64_t>> delays;
  std::string raw;
  int line = 0;
  int first_blank = 0;  // first blank line seen; only trailing blank lines are allowed
  while (in.next(raw, line + 1)) {
    ++line;
    if (static_cast<std::int64_t>(delays.size()) >= kMaxTracePackets) {
      throw TraceError(
          path, line,
          "more than " + std::to_string(kMaxTracePackets) + " packets (the limit of a trace)");
    }
    std::string_view text = raw;
    if (line == 1 && text.starts_with("\xEF\xBB\xBF")) text.remove_prefix(3);  // UTF-8 BOM
    if (!text.empty() && text.back() == '\r') text.remove_suffix(1);           // CRLF
    if (trim(text).empty()) {
      if (first_blank == 0) first_blank = line;
      continue;
    }
    if (first_blank != 0) {
      throw TraceError(path, first_blank,
                       "blank line inside the trace (only trailing blank lines are allowed)");
    }
    const std::size_t comma = text.find(',');
    const std::size_t columns =
        1 + static_cast<std::size_t>(std::count(text.begin(), text.end(), ','));
    if (columns != 2) {
      throw TraceError(path, line,
                       "expected 'seq,delay' (2 columns), got " + std::to_string(columns) +
                           (columns == 1 ? " column" : " columns") + " in '" + std::string(text) +
                           "'");
    }
    const std::string_view seq_field = trim(text.substr(0, comma));
    const std::string_view delay_field = trim(text.substr(comma + 1));
    if (seq_field == "seq" && delay_field == "delay") {
      if (line == 1) continue;
      throw TraceError(path, line, "header 'seq,delay' is only allowed on the first line");
    }

    std::optional<std::int64_t> delay;
    if (!delay_field.empty()) {
      delay = parse_count(delay_field);
      if (!delay) {
        throw TraceError(path, line,
                         "expected 'seq,delay' with a non-negative integer delay, got '" +
                             std::string(text) + "'");
      }
    }
    const std::optional<std::int64_t> seq = parse_count(seq_field);
    const auto expected = static_cast<std::int64_t>(delays.size());
    if (!seq || *seq != expected) {
      throw TraceError(path, line,
                       "expected 'seq,delay' with seq " + std::to_string(expected) +
                           " (consecutive from 0), got '" + std::string(text) + "'");
    }
    if (delays.empty() && first_row_line != nullptr) *first_row_line = line;
    delays.push_back(delay);
  }
  return delays;
}

}  // namespace ncosim::models
