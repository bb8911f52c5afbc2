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

#include "kernel/rng.h"
#include "models/mobility.h"

namespace ncosim::models {

inline constexpr std::int64_t kLost = -1;

// What links.csv and summary.csv's model_check report of a link (optional: a link without it
// reports no state, and its losses are taken as kCorrelated, see the *_of functions below).
class LinkReporting {
 public:
  virtual ~LinkReporting() = default;
  // How this link's losses compare with the model of every design (each packet's fate drawn
  // afresh from one delay law), for summary.csv's model_check note: kIndependent, the model
  // itself; kCorrelated, bursty or recorded losses of which a design uses only the marginal law
  // (the answer for a link without this interface, so that a new kind is never taken for the
  // model unless it says so); kPosition, losses driven by the vehicles' positions (SUMO), which
  // come in bursts.
  enum class LossModel { kIndependent, kCorrelated, kPosition };
  virtual LossModel loss_model() const = 0;
  // Mean length of a run of consecutive lost packets of one sender whose consecutive packets
  // are `gap` channel steps apart, where the model fixes it (nullopt: it does not, e.g. a
  // mobility-driven link, or a link with memory whose packets of this sender meet the channel
  // at irregular steps: gap = nullopt). 1 / (1 - loss_probability()) for independent losses.
  virtual std::optional<double> mean_loss_burst(std::optional<int> gap) const = 0;
  // What moves the channel's state, for links.csv (its `step` column and the packet gap of
  // mean_loss_burst): kPacket, one transition per packet sent; kPeriod, one per control period
  // (Link::advance()); kNone (the default), no chain state to report, counted like kPacket (one
  // step per packet of a sole sender): memoryless links, a replayed trace (one record per
  // packet), position-driven links. A link whose state moves with time must say kPeriod.
  enum class StateStep { kNone, kPacket, kPeriod };
  virtual StateStep state_step() const { return StateStep::kNone; }
  // The channel state the next packet meets (Markov kinds; -1: the link has no state) and the
  // stationary law of that state (empty without states): links.csv's state occupancy.
  virtual int state() const { return -1; }
  virtual std::vector<double> state_law() const { return {}; }
};

// A link bound to each run (optional): called once per run before Link::reset() with the run's
// mobility (null without [sumo]) and the campaign seed and run index: a mobility-driven link
// reads positions at send time and keys its draws by (seed, run, ...) (sumo/); a segmented trace
// picks the run's segment.
class RunBinding {
 public:
  virtual ~RunBinding() = default;
  virtual void bind_run(const MobilityRun* mobility, std::uint64_t seed, std::uint64_t run) = 0;
};

// A link that is a node of a packet-level network ([[network]], network/): the run hands its
// packets to that network's simulation, which decides their fate, instead of asking transmit().
struct NetworkAttachment {
  int network = 0;                   // index of the [[network]] in the scenario
  std::uint32_t bytes = 0;           // payload bytes of each packet
  double x = 0.0, y = 0.0, z = 0.0;  // the node's position (m; wireless networks)
  int vehicle = -1;  // the [sumo] vehicle the node rides (its index in the mobility), or -1
};

// What every link answers: the fate of each packet (what the kernel needs) and its law (what an
// offline design assumes). The optional interfaces above are reached through reporting(),
// run_binding() and network_attachment() (nullptr: the link has none).
class Link {
 public:
  virtual ~Link() = default;
  // A fresh instance with the same parameters (per-run state reset by reset()).
  virtual std::unique_ptr<Link> clone() const = 0;
  // Called once before period 0 of every run: a Markov link draws its initial state
  // from its stationary law here; a trace link rewinds.
  virtual void reset(kernel::Rng& rng) { (void)rng; }
  // Called with the send period k before every packet (periods never decrease within a run): a
  // time-driven link (Markov kinds with step = "period") moves its channel state to period k
  // here, one transition per period, so the state a packet meets depends on when it is sent.
  virtual void advance(std::int64_t period, kernel::Rng& rng) { (void)period, (void)rng; }
  // The fate of the next packet sent on this link: its delay in periods, or kLost.
  virtual std::int64_t transmit(kernel::Rng& rng) = 0;
  // Delays of every copy of the next packet that is delivered (empty: lost). Physical
  // links deliver at most one copy; the `independent` delay link delivers a copy per
  // delay d independently (the design model of Dolz et al. 2014, Remark 2.3).
  // True when copies are independent measurements (the design model): each delivered copy
  // then carries its own measurement noise, and estimators treat it as a new sample.
  virtual bool independent_copies() const { return false; }
  virtual void transmit_copies(kernel::Rng& rng, std::vector<std::int64_t>& delays) {
    delays.clear();
    const std::int64_t d = transmit(rng);
    if (d != kLost) delays.push_back(d);
  }
  // Marginal (stationary) probability that a packet arrives with delay exactly d,
  // for d = 0..max_delay (what an offline design assumes). The rest is lost or later.
  virtual std::vector<double> delay_pmf(int max_delay) const = 0;
  // Long-run probability that a packet is lost (never delivered).
  virtual double loss_probability() const = 0;
  // False when the law is not known before the run (a node of a [[network]] without a declared
  // design law): delay_pmf() and loss_probability() then throw config::ScenarioError naming the
  // key to give, and the reports leave the link's nominal values empty.
  virtual bool law_known() const { return true; }
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
  // The optional interfaces this link implements (nullptr: none).
  virtual const LinkReporting* reporting() const { return nullptr; }
  virtual RunBinding* run_binding() { return nullptr; }
  virtual const NetworkAttachment* network_attachment() const { return nullptr; }
};

// The reporting answers of any link: its LinkReporting's, or for a link without one, kCorrelated,
// kNone, no state (-1), no state law and no mean loss burst (nullopt).
LinkReporting::LossModel loss_model_of(const Link& link);
LinkReporting::StateStep state_step_of(const Link& link);
int state_of(const Link& link);
std::vector<double> state_law_of(const Link& link);
std::optional<double> mean_loss_burst_of(const Link& link, std::optional<int> gap);
// Binds `link` to a run when it implements RunBinding; nothing otherwise.
void bind_run(Link& link, const MobilityRun* mobility, std::uint64_t seed, std::uint64_t run);

// 1 / (1 - p): the mean length of a run of losses of independent packets lost with probability p
// (nullopt when p = 1: the run never ends).
std::optional<double> independent_loss_burst(double p);

// A memoryless link: each packet's fate drawn afresh from one law (the model of every design:
// loss_model() is kIndependent, mean_loss_burst() 1 / (1 - loss_probability()) for any gap).
class MemorylessLink : public Link, public LinkReporting {
 public:
  const LinkReporting* reporting() const override { return this; }
  LossModel loss_model() const override { return LossModel::kIndependent; }
  std::optional<double> mean_loss_burst(std::optional<int> gap) const override;
};

// Each packet: delay d with probability pmf[d] (d = 0..size-1); lost otherwise.
// With independent = true, every d is an independent copy delivered with probability
// pmf[d] (the design model of Dolz Remark 2.3), so a packet may arrive 0..size times.
class DelayPmfLink final : public MemorylessLink {
 public:
  explicit DelayPmfLink(std::vector<double> pmf, bool independent = false);
  std::unique_ptr<Link> clone() const override;
  std::int64_t transmit(kernel::Rng& rng) override;
  void transmit_copies(kernel::Rng& rng, std::vector<std::int64_t>& delays) override;
  bool independent_copies() const override { return independent_; }
  std::vector<double> delay_pmf(int max_delay) const override;
  double loss_probability() const override;

 private:
  std::vector<double> pmf_;
  std::vector<double> cdf_;
  bool independent_;
};

// Lost with probability `loss`, else delivered after `delay` periods.
class BernoulliLink final : public MemorylessLink {
 public:
  BernoulliLink(double loss, std::int64_t delay);
  std::unique_ptr<Link> clone() const override;
  std::int64_t transmit(kernel::Rng& rng) override;
  std::vector<double> delay_pmf(int max_delay) const override;
  double loss_probability() const override { return loss_; }

 private:
  double loss_;
  std::int64_t delay_;
};

// Lost with probability `loss`; else the delay is negative-binomial: the number of
// failures before the `successes`-th success of trials that succeed with probability p,
// P[d] = C(d + r - 1, d) p^r (1 - p)^d (Dolz example 2: p = 0.5, r = 3).
class NegativeBinomialLink final : public MemorylessLink {
 public:
  NegativeBinomialLink(int successes, double p, double loss);
  std::unique_ptr<Link> clone() const override;
  std::int64_t transmit(kernel::Rng& rng) override;
  std::vector<double> delay_pmf(int max_delay) const override;
  double loss_probability() const override { return loss_; }

 private:
  int successes_;
  double p_;
  double loss_;
};

// Schenato (2008): lambda_h = P[delay <= h] = cdf[h] for h < cdf.size(), and `tail` for
// every h >= cdf.size(); the packet is lost with probability 1 - tail.
class ArrivalCdfLink final : public MemorylessLink {
 public:
  ArrivalCdfLink(std::vector<double> cdf, double tail);
  std::unique_ptr<Link> clone() const override;
  std::int64_t transmit(kernel::Rng& rng) override;
  std::vector<double> delay_pmf(int max_delay) const override;
  double loss_probability() const override { return 1.0 - tail_; }

 private:
  std::vector<double> cdf_;  // non-decreasing, cdf_.back() <= tail_
  double tail_;
};

// Finite Markov chain: a packet meeting state s is lost with probability loss[s], else delayed
// by d with probability delay_pmf[s][d] (delay 0 when delay_pmf is empty). Stepping:
// kPacket: once per packet, after it (s_{k+1} ~ transition.row(s_k), k counting packets);
// kPeriod: once per control period (advance()), so packets sent in one period meet one state and
// a sender silent for g periods finds the chain g steps on. For a single sender sending every
// period both give the same draws in the same order, hence the same results. s_0 is drawn from
// `initial`, or from the stationary law when `initial` is empty.
// Gilbert–Elliott is the two-state case (make_gilbert_elliott).
class MarkovLink final : public Link, public LinkReporting {
 public:
  using Step = StateStep;  // kPacket or kPeriod
  MarkovLink(Eigen::MatrixXd transition, std::vector<double> loss,
             std::vector<std::vector<double>> delay_pmf = {}, std::vector<double> initial = {},
             Step step = Step::kPacket);
  void advance(std::int64_t period, kernel::Rng& rng) override;
  const LinkReporting* reporting() const override { return this; }
  // Bursty losses of which a design uses only the marginal law.
  LossModel loss_model() const override { return LossModel::kCorrelated; }
  StateStep state_step() const override { return step_; }
  std::unique_ptr<Link> clone() const override;
  void reset(kernel::Rng& rng) override;
  std::int64_t transmit(kernel::Rng& rng) override;
  std::vector<double> delay_pmf(int max_delay) const override;
  double loss_probability() const override;
  Eigen::Matrix2d on_time_chain() const override;
  // Stationary distribution of the chain (left eigenvector for eigenvalue 1).
  const Eigen::VectorXd& stationary() const { return stationary_; }
  int state() const override { return state_; }
  std::vector<double> state_law() const override;
  // P(L) / (P(L) - P(L, L)) with P(L, L) = sum_s pi_s lost_s (T^gap lost)_s.
  std::optional<double> mean_loss_burst(std::optional<int> gap) const override;

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
  Step step_ = Step::kPacket;
  std::int64_t period_ = 0;  // kPeriod: the period the state belongs to
};

// Two-state Markov link: state 0 = good, 1 = bad.
std::unique_ptr<MarkovLink> make_gilbert_elliott(double p_good_to_bad, double p_bad_to_good,
                                                 double loss_good, double loss_bad,
                                                 MarkovLink::Step step = MarkovLink::Step::kPacket);

// The transition probabilities of the Gilbert–Elliott chain with per-state losses lg < lb whose
// packets are lost with stationary probability `mean_loss` = P and whose runs of consecutive
// losses have mean length `mean_burst` = b. With pi_B = (P - lg) / (lb - lg), V = pi_B (1 - pi_B)
// (lb - lg)^2 and the chain's second eigenvalue lambda = 1 - p_gb - p_bg, the loss indicator has
// P(L, L) = P^2 + lambda V, so b = P / (P - P(L, L)) gives lambda = P (1 - P - 1/b) / V and
// p_gb = pi_B (1 - lambda), p_bg = (1 - pi_B)(1 - lambda). Valid when lg < P < lb and the two
// probabilities lie in [0, 1] with lambda < 1; otherwise `error` says why (at `error_key`).
struct GilbertElliottByMean {
  double p_good_to_bad = 0.0, p_bad_to_good = 0.0;
  std::string error, error_key;
};
GilbertElliottByMean gilbert_elliott_by_mean(double mean_loss, double mean_burst, double loss_good,
                                             double loss_bad);

// Replays a recorded trace: packet k (k-th packet sent on this link in the run) has
// delay delays[k] periods, or is lost when delays[k] is empty. Every run replays it
// from the start; with `segment` S > 0 the trace is cut into floor(size / S) segments of S
// rows and run r replays segment r mod floor(size / S) (the layout `ncosim record-link`
// writes: run r's packets in rows r S .. r S + S - 1). Sending more packets than the trace
// (or a segment) holds is a programmer error: the scenario reader checks the length before
// the run.
class TraceLink final : public Link, public LinkReporting, public RunBinding {
 public:
  explicit TraceLink(std::vector<std::optional<std::int64_t>> delays, std::size_t segment = 0);
  std::unique_ptr<Link> clone() const override;
  const LinkReporting* reporting() const override { return this; }
  RunBinding* run_binding() override { return this; }
  // Recorded losses: a design uses only their marginal law.
  LossModel loss_model() const override { return LossModel::kCorrelated; }
  void bind_run(const MobilityRun* mobility, std::uint64_t seed, std::uint64_t run) override;
  void reset(kernel::Rng& rng) override;
  std::int64_t transmit(kernel::Rng& rng) override;
  std::vector<double> delay_pmf(int max_delay) const override;
  double loss_probability() const override;
  // The trace's own mean loss-run length when one sender replays it (gap given).
  std::optional<double> mean_loss_burst(std::optional<int> gap) const override;
  std::size_t size() const { return delays_.size(); }
  std::optional<PacketBound> packet_bound() const override {
    if (segment_ > 0)
      return PacketBound{static_cast<std::int64_t>(segment_), "segment", "trace segment"};
    return PacketBound{static_cast<std::int64_t>(delays_.size()), "file", "trace"};
  }

 private:
  std::vector<std::optional<std::int64_t>> delays_;
  std::size_t segment_ = 0;  // rows per run (0: every run replays the whole trace from row 0)
  std::size_t start_ = 0;    // first row of this run's segment
  std::size_t next_ = 0;
};

// Reads a trace CSV: an optional header line "seq,delay", then one line per packet
// "seq,delay" with seq = 0, 1, 2, ... consecutive and delay a non-negative integer
// number of periods or empty (lost). Throws TraceError with the file, line and what
// is wrong for a missing file or a malformed line.
// what() is escaped (config/config.h escape_text): a line's bytes (NUL, ESC, invalid UTF-8) are
// printed as \xNN, never sent raw to the terminal or cut at a NUL.
struct TraceError : std::runtime_error {
  TraceError(std::string f, int l, const std::string& what);
  std::string file;
  int line;  // 0 when the file cannot be opened
};
// `first_row_line`, when given, receives the file line of row 0 (row i is on line
// first_row_line + i: a header only on line 1, blank lines only at the end).
std::vector<std::optional<std::int64_t>> load_trace(const std::string& path,
                                                    int* first_row_line = nullptr);

}  // namespace ncosim::models
