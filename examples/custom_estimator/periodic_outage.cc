// periodic_outage.cc — a new link kind: a deterministic duty cycle. Of every `cycle` packets
// the last `outage` are lost, the others arrive after `delay` periods. The phase is drawn
// uniformly at each run's start (reset), so the marginal law is stationary:
// P(lost) = outage / cycle.
// Keys: cycle (>= 1), outage (0..cycle), delay (>= 0, default 0).
#include <fmt/format.h>

#include <boost/random/uniform_int_distribution.hpp>

#include "kinds.h"

namespace {

class PeriodicOutage final : public ncosim::models::Link {
 public:
  PeriodicOutage(std::int64_t cycle, std::int64_t outage, std::int64_t delay)
      : cycle_(cycle), outage_(outage), delay_(delay) {}
  std::unique_ptr<Link> clone() const override {
    return std::make_unique<PeriodicOutage>(cycle_, outage_, delay_);
  }
  void reset(ncosim::kernel::Rng& rng) override {
    phase_ = boost::random::uniform_int_distribution<std::int64_t>(0, cycle_ - 1)(rng);
  }
  std::int64_t transmit(ncosim::kernel::Rng&) override {
    const std::int64_t slot = phase_;
    phase_ = (phase_ + 1) % cycle_;
    return slot >= cycle_ - outage_ ? ncosim::models::kLost : delay_;
  }
  std::vector<double> delay_pmf(int max_delay) const override {
    std::vector<double> pmf(static_cast<std::size_t>(max_delay) + 1, 0.0);
    if (delay_ <= max_delay) pmf[static_cast<std::size_t>(delay_)] = 1.0 - loss_probability();
    return pmf;
  }
  double loss_probability() const override {
    return static_cast<double>(outage_) / static_cast<double>(cycle_);
  }

 private:
  std::int64_t cycle_, outage_, delay_;
  std::int64_t phase_ = 0;
};

std::unique_ptr<ncosim::models::Link> read_periodic_outage(const ncosim::config::Table& t,
                                                           const ncosim::models::LinkContext&) {
  const std::int64_t cycle = t.integer("cycle"), outage = t.integer("outage"),
                     delay = t.integer_or("delay", 0);
  if (cycle < 1) t.fail("cycle", fmt::format("expected an integer >= 1, got {}", cycle));
  if (outage < 0 || outage > cycle)
    t.fail("outage", fmt::format("expected an integer in 0..{}, got {}", cycle, outage));
  if (delay < 0) t.fail("delay", fmt::format("expected an integer >= 0, got {}", delay));
  return std::make_unique<PeriodicOutage>(cycle, outage, delay);
}

}  // namespace

void register_periodic_outage(ncosim::models::LinkRegistry& registry) {
  registry.add("periodic_outage",
               "deterministic duty cycle (example extension): of every `cycle` packets the last "
               "`outage` are lost; "
               "delay",
               read_periodic_outage);
}
