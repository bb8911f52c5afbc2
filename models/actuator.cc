// models/actuator.cc — [[actuator]] reader and the per-run actuator stage.
#include "models/actuator.h"

#include <fmt/format.h>

#include <algorithm>

#include "models/sensor.h"  // read_link_ref

namespace ncosim::models {

ActuatorSpec read_actuator(const sim::Table& t, const std::vector<std::string>& links, int index) {
  ActuatorSpec a;
  a.name = t.string_or("name", fmt::format("u{}", index + 1));
  a.link = read_link_ref(t, links);
  a.on_loss = t.choice_or("on_loss", "hold", {"hold", "zero"}) == "hold"
                  ? ActuatorSpec::OnLoss::kHold
                  : ActuatorSpec::OnLoss::kZero;
  a.u0 = t.number_or("u0", 0.0);
  if (!std::isfinite(a.u0)) t.fail("u0", fmt::format("expected a finite number, got {}", a.u0));
  return a;
}

ActuatorStage::ActuatorStage(const std::vector<ActuatorSpec>& specs,
                             const std::vector<const Link*>& links, std::uint64_t seed,
                             std::uint64_t run) {
  applied_.resize(static_cast<Eigen::Index>(specs.size()));
  for (std::size_t i = 0; i < specs.size(); ++i) {
    Channel c;
    c.on_loss = specs[i].on_loss;
    c.rng = sim::make_stream(seed, run, sim::stream_id(sim::StreamKind::kActuatorLink, i));
    if (specs[i].link >= 0) {
      c.link = links[static_cast<std::size_t>(specs[i].link)]->clone();
      c.link->reset(c.rng);  // a Markov link starts from its stationary law
    }
    applied_(static_cast<Eigen::Index>(i)) = specs[i].u0;
    channels_.push_back(std::move(c));
  }
  counters_.resize(channels_.size());
}

int ActuatorStage::actuate(const Eigen::VectorXd& sent) {
  const int r = static_cast<int>(channels_.size());
  int mode = 0;
  for (int i = 0; i < r; ++i) {
    Channel& c = channels_[static_cast<std::size_t>(i)];
    bool delivered = true;
    if (c.link != nullptr) {
      c.link->advance(period_, c.rng);
      const int state = state_of(*c.link);
      const std::int64_t delay = c.link->transmit(c.rng);
      counters_[static_cast<std::size_t>(i)].record(delay, state);
      delivered = delay == 0;  // late = lost
    }
    if (delivered) {
      applied_(i) = sent(i);
    } else {
      mode |= 1 << (r - 1 - i);
      if (c.on_loss == ActuatorSpec::OnLoss::kZero) applied_(i) = 0.0;
    }
  }
  ++period_;
  return mode;
}

}  // namespace ncosim::models
