// models/link_stats.cc — summing and summarising the per-flow link counters.
#include "models/link_stats.h"

#include <algorithm>

namespace ncosim::models {

namespace {

void add_into(std::vector<std::int64_t>& to, const std::vector<std::int64_t>& from) {
  if (from.size() > to.size()) to.resize(from.size(), 0);
  for (std::size_t i = 0; i < from.size(); ++i) to[i] += from[i];
}

}  // namespace

void DelayBlocks::push() {
  delivered.push_back(fill_delivered);
  delay.push_back(fill_delay);
  fill = fill_delivered = fill_delay = 0;
  if (delivered.size() < 2 * kBlocks) return;
  for (std::size_t i = 0; i < kBlocks; ++i) {
    delivered[i] = delivered[2 * i] + delivered[2 * i + 1];
    delay[i] = delay[2 * i] + delay[2 * i + 1];
  }
  delivered.resize(kBlocks);
  delay.resize(kBlocks);
  size *= 2;
}

void StackCounters::add(const StackCounters& o) {
  attempts += o.attempts;
  retries += o.retries;
  add_into(drops, o.drops);
  if (o.busy_ns >= 0) busy_ns = std::max<std::int64_t>(busy_ns, 0) + o.busy_ns;
  simulated_ns += o.simulated_ns;
}

void LinkCounters::add(const LinkCounters& o) {
  sent += o.sent;
  delivered += o.delivered;
  add_into(copies, o.copies);
  add_into(bursts, o.bursts);
  add_into(states, o.states);
  if (o.stack) {
    if (!stack) stack.emplace();
    stack->add(*o.stack);
  }
}

BurstSummary summarise_bursts(const std::vector<std::int64_t>& bursts) {
  BurstSummary b;
  std::int64_t lost = 0;
  for (std::size_t i = 0; i < bursts.size(); ++i) {
    b.count += bursts[i];
    lost += bursts[i] * static_cast<std::int64_t>(i + 1);
    if (bursts[i] > 0) b.max = static_cast<std::int64_t>(i + 1);
  }
  if (b.count == 0) return b;
  b.mean = static_cast<double>(lost) / static_cast<double>(b.count);
  // Smallest L with count(length <= L) >= 0.95 count, in integers: 20 c >= 19 count.
  std::int64_t c = 0;
  for (std::size_t i = 0; i < bursts.size(); ++i) {
    c += bursts[i];
    if (20 * c >= 19 * b.count) {
      b.p95 = static_cast<std::int64_t>(i + 1);
      break;
    }
  }
  return b;
}

LinkNominal nominal_of(const Link& link, int max_delay, std::optional<int> gap) {
  LinkNominal n;
  if (!link.law_known()) return n;
  const double loss = link.loss_probability();
  if (loss >= 0.0 && loss <= 1.0) n.delivered_ratio = 1.0 - loss;
  n.delay_pmf = link.delay_pmf(std::max(0, max_delay));
  n.states = state_law_of(link);
  n.burst_mean = mean_loss_burst_of(link, gap);
  return n;
}

}  // namespace ncosim::models
