// models/input.cc — [input] readers and the built-in inputs none, white and state_feedback.
#include "models/input.h"

#include <fmt/format.h>

#include "config/keys.h"
#include "models/noise.h"

namespace ncosim::models {

namespace {

void require_input_channel(const config::Table& t, const LinearPlant& plant) {
  if (plant.nu() == 0) {
    t.fail("kind", "expected a plant with an input matrix (Bu or Bc), got a plant without input");
  }
}

// u = 0.
class NoInput final : public Controller {
 public:
  void compute(const ControlContext&, Eigen::VectorXd&) override {}
};
class NoInputDesign final : public ControllerDesign {
 public:
  bool closes_loop() const override { return false; }
  bool sees_outputs() const override { return false; }
  std::unique_ptr<Controller> instantiate() const override { return std::make_unique<NoInput>(); }
};

// u ~ N(0, diag(std^2)), drawn from the run's input stream.
class WhiteInput final : public Controller {
 public:
  explicit WhiteInput(const Eigen::VectorXd& std) : std_(std) {}
  void compute(const ControlContext& c, Eigen::VectorXd& u) override {
    draw_standard_normal(*c.rng, u);
    u = u.cwiseProduct(std_);
  }

 private:
  const Eigen::VectorXd& std_;
};
class WhiteInputDesign final : public ControllerDesign {
 public:
  explicit WhiteInputDesign(Eigen::VectorXd std) : std_(std::move(std)) {}
  bool closes_loop() const override { return false; }
  bool sees_outputs() const override { return false; }
  std::unique_ptr<Controller> instantiate() const override {
    return std::make_unique<WhiteInput>(std_);
  }

 private:
  Eigen::VectorXd std_;
};

// u = -K x on the true state, or -K xhat on the source estimator's estimate.
class StateFeedback final : public Controller {
 public:
  explicit StateFeedback(const Eigen::MatrixXd& K) : K_(K) {}
  void compute(const ControlContext& c, Eigen::VectorXd& u) override {
    u.noalias() = -K_ * (c.estimate != nullptr ? *c.estimate : *c.x);
  }

 private:
  const Eigen::MatrixXd& K_;
};
class StateFeedbackDesign final : public ControllerDesign {
 public:
  StateFeedbackDesign(Eigen::MatrixXd K, std::string source)
      : K_(std::move(K)), source_(std::move(source)) {}
  std::string estimate_source() const override { return source_ == "plant" ? "" : source_; }
  const char* source_key() const override { return "source"; }
  bool sees_outputs() const override { return false; }
  std::unique_ptr<Controller> instantiate() const override {
    return std::make_unique<StateFeedback>(K_);
  }

 private:
  Eigen::MatrixXd K_;
  std::string source_;
};

InputSpec with(std::shared_ptr<ControllerDesign> design) {
  InputSpec s;
  s.source = design->estimate_source();
  s.controller = std::move(design);
  return s;
}

using config::Key;

const config::Keys& white_keys() {
  static const config::Keys keys{
      Key::vector("std").help(
          "standard deviation of each input channel (>= 0; one value for every channel, or one "
          "per channel)"),
  };
  return keys;
}

const config::Keys& state_feedback_keys() {
  static const config::Keys keys{
      Key::matrix("K").help("the gain, nu x n: u = -K x"),
      Key::string("source").or_default("plant").help(
          "\"plant\" (the true state) or the name of the [[estimator]] whose estimate is fed "
          "back"),
  };
  return keys;
}

InputSpec read_none(const config::Table&, const LinearPlant&) { return with(no_input()); }

InputSpec read_white(const config::Table& table, const LinearPlant& plant) {
  require_input_channel(table, plant);
  const config::KeyReader t(table, white_keys());
  Eigen::VectorXd std = t.vector("std");
  if (std.size() == 1 && plant.nu() > 1) std = Eigen::VectorXd::Constant(plant.nu(), std(0));
  if (std.size() != plant.nu()) {
    t.fail("std", plant.nu() == 1
                      ? fmt::format("expected 1 entry (the input size), got {}", std.size())
                      : fmt::format("expected 1 or {} entries (the input size), got {}", plant.nu(),
                                    std.size()));
  }
  if (std.minCoeff() < 0)
    t.fail("std", fmt::format("expected non-negative standard deviations, got {}",
                              fmt::join(std.data(), std.data() + std.size(), ", ")));
  return with(std::make_shared<WhiteInputDesign>(std::move(std)));
}

InputSpec read_state_feedback(const config::Table& table, const LinearPlant& plant) {
  require_input_channel(table, plant);
  const config::KeyReader t(table, state_feedback_keys());
  Eigen::MatrixXd K = t.matrix("K");
  config::require_shape(table, "K", K, plant.nu(), plant.n());
  const std::string source = t.string("source");
  if (source.empty()) t.fail("source", "expected \"plant\" or an estimator name, got \"\"");
  return with(std::make_shared<StateFeedbackDesign>(std::move(K), source));
}

InputSpec read_controller(const config::Table& t, const LinearPlant& plant,
                          std::shared_ptr<ControllerDesign> (*reader)(const config::Table&,
                                                                      Eigen::Index)) {
  require_input_channel(t, plant);
  return with(reader(t, plant.nu()));
}

}  // namespace

std::shared_ptr<ControllerDesign> no_input() {
  static const auto none = std::make_shared<NoInputDesign>();
  return none;
}

void register_inputs(InputRegistry& registry) {
  registry.add("none", "u = 0", config::Keys{}, read_none);
  registry.add("white", "u ~ N(0, std^2) each period, independent channels: std", white_keys(),
               read_white);
  registry.add("state_feedback",
               "u = -K x on the true state (source = \"plant\") or on an estimator's estimate "
               "(source = its name): K, source",
               state_feedback_keys(), read_state_feedback);
  registry.add(
      "relay",
      "relay with dead zone, output i drives input i: u_i = -level if y_i > dead_zone, +level if "
      "y_i < -dead_zone, else 0; sees = \"true\" | \"measured\" | \"received\"",
      relay_keys(), [](const config::Table& t, const LinearPlant& p) {
        return read_controller(t, p, read_relay);
      });
  registry.add(
      "pi",
      "discrete PI with reference weighting on one sensor output: u = kp (b r - y) + ki T sum(r - "
      "y); "
      "kp, ki, b, reference = {kind = \"square\", low, high, period} or {value}, feedback = "
      "\"received\" | \"measured\" | \"true\" | an estimator name, sensor, output, u_min, u_max",
      pi_keys(),
      [](const config::Table& t, const LinearPlant& p) { return read_controller(t, p, read_pi); });
}

}  // namespace ncosim::models
