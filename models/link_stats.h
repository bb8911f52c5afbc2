// models/link_stats.h — what a link did to the packets of one sender, counted cheaply during a
// run (a few integer increments per packet), and the values the link's model predicts for them.
// A "flow" is one (link, sender) pair: packets of several sensors crossing one [[link]] share its
// channel state but are counted apart. sim/link_stats.* turns the counters into links.csv.
#pragma once

#include <algorithm>
#include <cstdint>
#include <optional>
#include <vector>

#include "models/link.h"

namespace ncosim::models {

// What the protocol stack of a network node did (links of kind `network` only; network/network.h
// MacCounters, summed over runs): frames put on the air and of them retransmissions, packets
// dropped by cause (index: network::Drop), the time the node found the channel busy (-1: its
// network's kind does not expose it) and the simulated time of the network (ns).
struct StackCounters {
  std::int64_t attempts = 0, retries = 0;
  std::vector<std::int64_t> drops;
  std::int64_t busy_ns = -1;
  std::int64_t simulated_ns = 0;
  void add(const StackCounters& o);
};

// One run's packet delays in the order they were counted, as means over blocks of equal size:
// what the overload test (sim/run/overload.h) fits a trend to. The blocks start one packet long;
// when 2 kBlocks are full, neighbours are merged and the size doubles, so a run of n >= kBlocks
// packets ends with kBlocks .. 2 kBlocks - 1 full blocks whatever n (the block being filled is
// left out). A per-run record: LinkCounters::add does not sum it.
struct DelayBlocks {
  static constexpr std::size_t kBlocks = 32;
  std::int64_t size = 1;                // packets per block
  std::vector<std::int64_t> delivered;  // per full block: packets delivered
  std::vector<std::int64_t> delay;      // per full block: their delays summed (periods)
  std::int64_t fill = 0, fill_delivered = 0, fill_delay = 0;  // the block being filled

  // One packet: its delay (its first copy's), or kLost.
  void add(std::int64_t d) {
    ++fill;
    if (d != kLost) {
      ++fill_delivered;
      fill_delay += d;
    }
    if (fill == size) push();
  }

 private:
  void push();  // the filled block, merging when 2 kBlocks are full
};

struct LinkCounters {
  std::int64_t sent = 0;       // packets handed to the link
  std::int64_t delivered = 0;  // packets with at least one delivered copy
  // copies[d]: delivered copies with delay d periods (a physical link delivers at most one copy
  // per packet; the `independent` delay link may deliver several).
  std::vector<std::int64_t> copies;
  // bursts[L - 1]: maximal runs of exactly L consecutive lost packets of this flow. A run still
  // open at the end of the run is counted with its observed length (close()).
  std::vector<std::int64_t> bursts;
  // states[s]: packets sent while the link's channel was in state s (Markov kinds only).
  std::vector<std::int64_t> states;
  std::int64_t open_burst = 0;         // losses in a row so far (not yet in `bursts`)
  std::optional<StackCounters> stack;  // a network node's stack (nullopt: not a network link)
  DelayBlocks blocks;                  // this run's delays in order (not summed by add)

  // One packet: the delays of its delivered copies (empty: lost) and the channel state it met
  // (-1: the link has no state).
  void record(const std::vector<std::int64_t>& delays, int state) {
    ++sent;
    count_state(state);
    if (delays.empty()) {
      ++open_burst;
      blocks.add(kLost);
      return;
    }
    ++delivered;
    close();
    std::int64_t first = delays.front();
    for (const std::int64_t d : delays) {
      count_copy(d);
      first = std::min(first, d);
    }
    blocks.add(first);
  }
  // One packet of a physical link: its delay, or kLost.
  void record(std::int64_t delay, int state) {
    ++sent;
    count_state(state);
    blocks.add(delay);
    if (delay == kLost) {
      ++open_burst;
      return;
    }
    ++delivered;
    close();
    count_copy(delay);
  }
  // Ends the current loss run (if any) and counts it.
  void close() {
    if (open_burst == 0) return;
    const auto i = static_cast<std::size_t>(open_burst - 1);
    if (i >= bursts.size()) bursts.resize(i + 1, 0);
    ++bursts[i];
    open_burst = 0;
  }
  // Adds the (closed) counters of another run.
  void add(const LinkCounters& o);

 private:
  void count_state(int state) {
    if (state < 0) return;
    const auto s = static_cast<std::size_t>(state);
    if (s >= states.size()) states.resize(s + 1, 0);
    ++states[s];
  }
  void count_copy(std::int64_t d) {
    const auto i = static_cast<std::size_t>(d);
    if (i >= copies.size()) copies.resize(i + 1, 0);
    ++copies[i];
  }
};

// Summary of the loss-run lengths: count, mean, 95th percentile (the smallest L with at least
// 95 % of the runs of length <= L) and maximum. Empty optionals when there is no run.
struct BurstSummary {
  std::int64_t count = 0;
  std::optional<double> mean;
  std::optional<std::int64_t> p95, max;
};
BurstSummary summarise_bursts(const std::vector<std::int64_t>& bursts);

// The model's predictions for a flow, where the model makes one.
struct LinkNominal {
  std::optional<double> delivered_ratio;  // 1 - loss_probability()
  std::vector<double> delay_pmf;          // per packet: P(a copy arrives with delay d), d = 0..max
  std::optional<double> burst_mean;       // mean loss-run length of the flow's packet sequence
  std::vector<double> states;             // stationary law of the channel state (Markov kinds)
};
// `gap`: channel steps between two consecutive packets of the flow (1 with per-packet stepping
// and a single sender; the sender's period in periods with time-driven stepping); nullopt when
// the flow's packets meet the chain at irregular steps (then no nominal burst for Markov kinds).
LinkNominal nominal_of(const Link& link, int max_delay, std::optional<int> gap);

}  // namespace ncosim::models
