// models/actuator.cc — [[actuator]] reader and the per-run actuator stage.
#include "models/actuator.h"

#include <fmt/format.h>

#include <algorithm>

#include "models/sensor.h"  // read_link_ref

namespace ncosim::models {

const config::Keys& actuator_keys() {
  static const config::Keys keys{
      config::Key::string("name").optional("\"u1\", \"u2\", ...").help("unique among actuators"),
      config::Key::string("link")
          .optional("ideal (always delivered)")
          .help("the name of a [[link]]; each actuator uses its own instance of the link"),
      config::Key::choice("on_loss", {"hold", "zero"})
          .or_default("hold")
          .help("what is applied when the command is not delivered"),
      config::Key::number("u0").or_default(0.0).help("the value held before period 0 (hold)"),
  };
  return keys;
}

ActuatorSpec read_actuator(const config::Table& table, const std::vector<std::string>& links,
                           int index) {
  const config::KeyReader t(table, actuator_keys());
  ActuatorSpec a;
  a.name = t.opt_string("name").value_or(fmt::format("u{}", index + 1));
  a.link = read_link_ref(t, links);
  a.on_loss =
      t.string("on_loss") == "hold" ? ActuatorSpec::OnLoss::kHold : ActuatorSpec::OnLoss::kZero;
  a.u0 = t.number("u0");  // finite: Table::number refuses inf and nan
  return a;
}

ActuatorStage::ActuatorStage(const std::vector<ActuatorSpec>& specs,
                             const std::vector<const Link*>& links, std::uint64_t seed,
                             std::uint64_t run) {
  applied_.resize(static_cast<Eigen::Index>(specs.size()));
  for (std::size_t i = 0; i < specs.size(); ++i) {
    Channel c;
    c.on_loss = specs[i].on_loss;
    c.rng = kernel::make_stream(seed, run, kernel::stream_id(kernel::StreamKind::kActuatorLink, i));
    if (specs[i].link >= 0) {
      c.link = links[static_cast<std::size_t>(specs[i].link)]->clone();
      c.link->reset(c.rng);  // a Markov link starts from its stationary law
      c.networked = c.link->network_attachment() != nullptr;
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
    if (c.networked) {
      c.pending = sent(i);
      continue;
    }
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

int ActuatorStage::resolve(int i, bool delivered) {
  const Channel& c = channels_[static_cast<std::size_t>(i)];
  if (delivered) {
    applied_(i) = c.pending;
    return 0;
  }
  if (c.on_loss == ActuatorSpec::OnLoss::kZero) applied_(i) = 0.0;
  return 1 << (static_cast<int>(channels_.size()) - 1 - i);
}

}  // namespace ncosim::models
