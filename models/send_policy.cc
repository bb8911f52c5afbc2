// models/send_policy.cc — the built-in send policies: periodic and send_on_delta.
#include "models/send_policy.h"

#include <fmt/format.h>

#include "config/keys.h"
#include "models/sensor.h"

namespace ncosim::models {

namespace {

class Periodic final : public SendPolicy {
 public:
  bool decide(const Eigen::Ref<const Eigen::VectorXd>&) override { return true; }
};

class PeriodicDesign final : public SendPolicyDesign {
 public:
  std::unique_ptr<SendPolicy> instantiate() const override { return std::make_unique<Periodic>(); }
  std::string name() const override { return "periodic"; }
  bool sends_every_sample() const override { return true; }
};

// |y_i - y_i(last sent)| >= delta_i for some output i; the first sample is always sent.
class SendOnDelta final : public SendPolicy {
 public:
  explicit SendOnDelta(const Eigen::VectorXd& delta)
      : delta_(delta), last_(Eigen::VectorXd::Zero(delta.size())) {}
  bool decide(const Eigen::Ref<const Eigen::VectorXd>& sample) override {
    const bool send = !has_sent_ || ((sample - last_).cwiseAbs().array() >= delta_.array()).any();
    if (send) {
      last_ = sample;
      has_sent_ = true;
    }
    return send;
  }
  const Eigen::VectorXd* held() const override { return &last_; }

 private:
  const Eigen::VectorXd& delta_;
  Eigen::VectorXd last_;
  bool has_sent_ = false;
};

class SendOnDeltaDesign final : public SendPolicyDesign {
 public:
  explicit SendOnDeltaDesign(Eigen::VectorXd delta) : delta_(std::move(delta)) {}
  std::unique_ptr<SendPolicy> instantiate() const override {
    return std::make_unique<SendOnDelta>(delta_);
  }
  std::string name() const override { return "send_on_delta"; }
  const Eigen::VectorXd* deadband() const override { return &delta_; }

 private:
  Eigen::VectorXd delta_;
};

using config::Key;

const config::Keys& send_on_delta_keys() {
  static const config::Keys keys{
      Key::vector("delta").help(
          "threshold per output (finite, >= 0; one value for every output, or one per output)"),
  };
  return keys;
}

std::shared_ptr<const SendPolicyDesign> read_periodic(const config::Table& t, const SensorSpec&) {
  if (t.has("delta"))
    t.fail("delta",
           "expected no threshold with policy = \"periodic\" (set policy = \"send_on_delta\")");
  return periodic_policy();
}

std::shared_ptr<const SendPolicyDesign> read_send_on_delta(const config::Table& table,
                                                           const SensorSpec& s) {
  const config::KeyReader t(table, send_on_delta_keys());
  Eigen::VectorXd delta = t.vector("delta");
  if (delta.size() == 1 && s.ny() > 1) delta = Eigen::VectorXd::Constant(s.ny(), delta(0));
  if (delta.size() != s.ny()) {
    t.fail("delta", fmt::format("expected 1 or {} entries (one threshold per output), got {}",
                                s.ny(), delta.size()));
  }
  if (!delta.allFinite() || delta.minCoeff() < 0.0)
    t.fail("delta", fmt::format("expected finite thresholds >= 0, got {}",
                                fmt::join(delta.data(), delta.data() + delta.size(), ", ")));
  if (s.buffer > 0)
    table.fail("buffer", fmt::format("expected buffer = 0 with policy = \"send_on_delta\", got {}",
                                     s.buffer));
  return std::make_shared<SendOnDeltaDesign>(std::move(delta));
}

}  // namespace

std::shared_ptr<const SendPolicyDesign> periodic_policy() {
  static const auto p = std::make_shared<const PeriodicDesign>();
  return p;
}

void register_send_policies(SendPolicyRegistry& registry) {
  registry.add("periodic", "every sample is sent (default)", config::Keys{}, read_periodic);
  registry.add("send_on_delta",
               "a sample is sent when |y_i - y_i(last sent)| >= delta_i for some output i (the "
               "first is always "
               "sent): delta (one threshold, or one per output); buffer = 0",
               send_on_delta_keys(), read_send_on_delta);
}

}  // namespace ncosim::models
