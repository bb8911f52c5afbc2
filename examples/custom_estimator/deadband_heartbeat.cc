// deadband_heartbeat.cc — a new send policy: send-on-delta with a heartbeat. A sample is sent
// when some output moved by at least `delta` since the last sample sent, or when `max_silence`
// samples in a row were not sent (the receiver then knows the sensor is alive); the first
// sample is always sent. Keys: delta (one threshold, or one per output), max_silence >= 1.
#include <fmt/format.h>

#include "kinds.h"
#include "models/sensor.h"

namespace {

using ncosim::models::SendPolicy;
using ncosim::models::SendPolicyDesign;

class DeadbandHeartbeat final : public SendPolicy {
 public:
  DeadbandHeartbeat(const Eigen::VectorXd& delta, int max_silence)
      : delta_(delta), max_silence_(max_silence), last_(Eigen::VectorXd::Zero(delta.size())) {}

  bool decide(const Eigen::Ref<const Eigen::VectorXd>& y) override {
    const bool send = !has_sent_ || silent_ >= max_silence_ ||
                      ((y - last_).cwiseAbs().array() >= delta_.array()).any();
    if (send) {
      last_ = y;  // same size: no allocation per period
      has_sent_ = true;
      silent_ = 0;
    } else {
      ++silent_;
    }
    return send;
  }
  const Eigen::VectorXd* held() const override { return &last_; }

 private:
  const Eigen::VectorXd& delta_;
  int max_silence_;
  Eigen::VectorXd last_;
  bool has_sent_ = false;
  int silent_ = 0;
};

class DeadbandHeartbeatDesign final : public SendPolicyDesign {
 public:
  DeadbandHeartbeatDesign(Eigen::VectorXd delta, int max_silence)
      : delta_(std::move(delta)), max_silence_(max_silence) {}
  std::unique_ptr<SendPolicy> instantiate() const override {
    return std::make_unique<DeadbandHeartbeat>(delta_, max_silence_);
  }
  std::string name() const override { return "deadband_heartbeat"; }

 private:
  Eigen::VectorXd delta_;
  int max_silence_;
};

std::shared_ptr<const SendPolicyDesign> read_deadband_heartbeat(
    const ncosim::config::Table& t, const ncosim::models::SensorSpec& s) {
  Eigen::VectorXd delta = t.vector("delta");
  if (delta.size() == 1) delta = Eigen::VectorXd::Constant(s.ny(), delta(0));
  if (delta.size() != s.ny() || !delta.allFinite() || delta.minCoeff() < 0.0) {
    t.fail("delta", fmt::format("expected 1 or {} finite thresholds >= 0", s.ny()));
  }
  const auto max_silence = t.integer("max_silence");
  if (max_silence < 1 || max_silence > 1000000) {
    t.fail("max_silence", fmt::format("expected an integer in 1..1000000, got {}", max_silence));
  }
  return std::make_shared<DeadbandHeartbeatDesign>(std::move(delta), static_cast<int>(max_silence));
}

}  // namespace

void register_deadband_heartbeat(ncosim::models::SendPolicyRegistry& registry) {
  registry.add(
      "deadband_heartbeat",
      "send when some output moved by >= delta since the last sample sent, or after max_silence "
      "samples not sent: delta, max_silence",
      read_deadband_heartbeat);
}
