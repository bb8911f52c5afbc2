// models/link.h — network links (channels): the fate of each packet crossing them.
// A link decides, at send time, whether a packet is lost or after how many whole control
// periods it arrives; the kernel then schedules the arrival event at send time + delay.
// Links run in the kernel, one instance per run (clone()), with their own random stream.
// Invalid parameters are rejected by the scenario reader before a link is built; the
// constructors here only NCOSIM_CHECK them.
#pragma once

#include <Eigen/Dense>
#include <cstdint>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "config/mobility.h"
#include "kernel/rng.h"

namespace ncosim::models {

inline constexpr std::int64_t kLost = -1;

class Link {
 public:
  virtual ~Link() = default;
  // A fresh instance with the same parameters (per-run state reset by reset()).
  virtual std::unique_ptr<Link> clone() const = 0;
  // Called once before period 0 of every run: a Markov link draws its initial state
  // from its stationary law here; a trace link rewinds.
  virtual void reset(sim::Rng& rng) { (void)rng; }
  // Called once per run before reset() with the run's mobility (null without [sumo]) and the
  // campaign seed and run index: a mobility-driven link reads positions at send time and
  // keys its draws by (seed, run, ...) (sumo/).
  virtual void bind_run(const sim::MobilityRun* mobility, std::uint64_t seed, std::uint64_t run) {
    (void)mobility, (void)seed, (void)run;
  }
  // The fate of the next packet sent on this link: its delay in periods, or kLost.
  virtual std::int64_t transmit(sim::Rng& rng) = 0;
  // Delays of every copy of the next packet that is delivered (empty: lost). Physical
  // links deliver at most one copy; the `independent` delay link delivers a copy per
  // delay d independently (the design model of Dolz et al. 2014, Remark 2.3).
  // True when copies are independent measurements (the design model): each delivered copy
  // then carries its own measurement noise, and estimators treat it as a new sample.
  virtual bool independent_copies() const { return false; }
  virtual void transmit_copies(sim::Rng& rng, std::vector<std::int64_t>& delays) {
    delays.clear();
    const std::int64_t d = transmit(rng);
    if (d != kLost) delays.push_back(d);
  }
  // Marginal (stationary) probability that a packet arrives with delay exactly d,
  // for d = 0..max_delay (what an offline design assumes). The rest is lost or later.
  virtual std::vector<double> delay_pmf(int max_delay) const = 0;
  // Long-run probability that a packet is lost (never delivered).
  virtual double loss_probability() const = 0;
  // The on-time process a[k] = 1 when packet k arrives with delay 0 (what an actuator needs)
  // as a two-state chain over (0 = delivered on time, 1 = not): M(i, j) = P(a[k] = j |
  // a[k-1] = i) under the stationary law. Exact for independent packets and for a Markov link
  // whose states deliver on time with probability 0 or 1; otherwise the one-step Markov fit
  // of the stationary pair law. Default: independent packets, P(on time) = delay_pmf(0)[0].
  virtual Eigen::Matrix2d on_time_chain() const;
  // The most packets one run may send over this link, when bounded (a replayed trace holds a
  // fixed number): the scenario reader refuses, before t = 0, sensors or actuators that would
  // send more, naming the table key `key` and calling the link a `noun` ("trace"). nullopt:
  // unbounded (every random link).
  struct PacketBound {
    std::int64_t packets;
    std::string_view key;
    std::string_view noun;
  };
  virtual std::optional<PacketBound> packet_bound() const { return std::nullopt; }
};

// Each packet: delay d with probability pmf[d] (d = 0..size-1); lost otherwise.
// With independent = true, every d is an independent copy delivered with probability
// pmf[d] (the design model of Dolz Remark 2.3), so a packet may arrive 0..size times.
class DelayPmfLink final : public Link {
 public:
  explicit DelayPmfLink(std::vector<double> pmf, bool independent = false);
  std::unique_ptr<Link> clone() const override;
  std::int64_t transmit(sim::Rng& rng) override;
  void transmit_copies(sim::Rng& rng, std::vector<std::int64_t>& delays) override;
  bool independent_copies() const override { return independent_; }
  std::vector<double> delay_pmf(int max_delay) const override;
  double loss_probability() const override;

 private:
  std::vector<double> pmf_;
  std::vector<double> cdf_;
  bool independent_;
};

// Lost with probability `loss`, else delivered after `delay` periods.
class BernoulliLink final : public Link {
 public:
  BernoulliLink(double loss, std::int64_t delay);
  std::unique_ptr<Link> clone() const override;
  std::int64_t transmit(sim::Rng& rng) override;
  std::vector<double> delay_pmf(int max_delay) const override;
  double loss_probability() const override { return loss_; }

 private:
  double loss_;
  std::int64_t delay_;
};

// Lost with probability `loss`; else the delay is negative-binomial: the number of
// failures before the `successes`-th success of trials that succeed with probability p,
// P[d] = C(d + r - 1, d) p^r (1 - p)^d (Dolz example 2: p = 0.5, r = 3).
class NegativeBinomialLink final : public Link {
 public:
  NegativeBinomialLink(int successes, double p, double loss);
  std::unique_ptr<Link> clone() const override;
  std::int64_t transmit(sim::Rng& rng) override;
  std::vector<double> delay_pmf(int max_delay) const override;
  double loss_probability() const override { return loss_; }

 private:
  int successes_;
  double p_;
  double loss_;
};

// Schenato (2008): lambda_h = P[delay <= h] = cdf[h] for h < cdf.size(), and `tail` for
// every h >= cdf.size(); the packet is lost with probability 1 - tail.
class ArrivalCdfLink final : public Link {
 public:
  ArrivalCdfLink(std::vector<double> cdf, double tail);
  std::unique_ptr<Link> clone() const override;
  std::int64_t transmit(sim::Rng& rng) override;
  std::vector<double> delay_pmf(int max_delay) const override;
  double loss_probability() const override { return 1.0 - tail_; }

 private:
  std::vector<double> cdf_;  // non-decreasing, cdf_.back() <= tail_
  double tail_;
};

// Finite Markov chain stepped once per packet: packet k is lost with probability
// loss[s_k], else delayed by d with probability delay_pmf[s_k][d] (delay 0 when
// delay_pmf is empty); then s_{k+1} ~ transition.row(s_k). s_0 is drawn from
// `initial`, or from the stationary law when `initial` is empty.
// Gilbert–Elliott is the two-state case (make_gilbert_elliott).
class MarkovLink final : public Link {
 public:
  MarkovLink(Eigen::MatrixXd transition, std::vector<double> loss,
             std::vector<std::vector<double>> delay_pmf = {}, std::vector<double> initial = {});
  std::unique_ptr<Link> clone() const override;
  void reset(sim::Rng& rng) override;
  std::int64_t transmit(sim::Rng& rng) override;
  std::vector<double> delay_pmf(int max_delay) const override;
  double loss_probability() const override;
  Eigen::Matrix2d on_time_chain() const override;
  // Stationary distribution of the chain (left eigenvector for eigenvalue 1).
  const Eigen::VectorXd& stationary() const { return stationary_; }
  int state() const { return state_; }

 private:
  Eigen::MatrixXd transition_;
  std::vector<double> loss_;
  std::vector<std::vector<double>> delay_pmf_;
  std::vector<double> initial_;
  Eigen::VectorXd stationary_;
  // Precomputed for transmit(): row-major cumulative rows of `transition`, the cumulative
  // per-state delay pmfs (empty: delay 0), the cumulative law of s_0.
  std::vector<double> transition_cdf_;
  std::vector<std::vector<double>> delay_cdf_;
  std::vector<double> initial_cdf_;
  int state_ = 0;
};

// Two-state Markov link: state 0 = good, 1 = bad.
std::unique_ptr<MarkovLink> make_gilbert_elliott(double p_good_to_bad, double p_bad_to_good,
                                                 double loss_good, double loss_bad);

// Replays a recorded trace: packet k (k-th packet sent on this link in the run) has
// delay delays[k] periods, or is lost when delays[k] is empty. Every run replays it
// from the start. Sending more packets than the trace holds is a programmer error:
// the scenario reader checks the length before the run.
class TraceLink final : public Link {
 public:
  explicit TraceLink(std::vector<std::optional<std::int64_t>> delays);
  std::unique_ptr<Link> clone() const override;
  void reset(sim::Rng& rng) override;
  std::int64_t transmit(sim::Rng& rng) override;
  std::vector<double> delay_pmf(int max_delay) const override;
  double loss_probability() const override;
  std::size_t size() const { return delays_.size(); }
  std::optional<PacketBound> packet_bound() const override {
    return PacketBound{static_cast<std::int64_t>(delays_.size()), "file", "trace"};
  }

 private:
  std::vector<std::optional<std::int64_t>> delays_;
  std::size_t next_ = 0;
};

// Reads a trace CSV: an optional header line "seq,delay", then one line per packet
// "seq,delay" with seq = 0, 1, 2, ... consecutive and delay a non-negative integer
// number of periods or empty (lost). Throws TraceError with the file, line and what
// is wrong for a missing file or a malformed line.
struct TraceError : std::runtime_error {
  TraceError(std::string f, int l, const std::string& what)
      : std::runtime_error(what), file(std::move(f)), line(l) {}
  std::string file;
  int line;  // 0 when the file cannot be opened
};
std::vector<std::optional<std::int64_t>> load_trace(const std::string& path);

}  // namespace ncosim::models
