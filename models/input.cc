// models/input.cc — [input] readers.
#include "models/input.h"

#include <fmt/format.h>

namespace ncosim::models {

namespace {

void require_input_channel(const sim::Table& t, const LinearPlant& plant) {
  if (plant.nu() == 0) {
    t.fail("kind", "expected a plant with an input matrix (Bu or Bc), got a plant without input");
  }
}

InputSpec read_none(const sim::Table&, const LinearPlant&) { return {}; }

InputSpec read_white(const sim::Table& t, const LinearPlant& plant) {
  require_input_channel(t, plant);
  InputSpec s;
  s.kind = InputSpec::Kind::kWhite;
  s.std = t.vector("std");
  if (s.std.size() == 1 && plant.nu() > 1) s.std = Eigen::VectorXd::Constant(plant.nu(), s.std(0));
  if (s.std.size() != plant.nu()) {
    t.fail("std", plant.nu() == 1
                      ? fmt::format("expected 1 entry (the input size), got {}", s.std.size())
                      : fmt::format("expected 1 or {} entries (the input size), got {}", plant.nu(),
                                    s.std.size()));
  }
  if (s.std.minCoeff() < 0) t.fail("std", "expected non-negative standard deviations");
  return s;
}

InputSpec read_state_feedback(const sim::Table& t, const LinearPlant& plant) {
  require_input_channel(t, plant);
  InputSpec s;
  s.kind = InputSpec::Kind::kStateFeedback;
  s.K = t.matrix("K");
  sim::require_shape(t, "K", s.K, plant.nu(), plant.n());
  s.source = t.string_or("source", "plant");
  return s;
}

InputSpec read_controller(const sim::Table& t, const LinearPlant& plant,
                          std::shared_ptr<ControllerDesign> (*reader)(const sim::Table&, Eigen::Index)) {
  require_input_channel(t, plant);
  InputSpec s;
  s.kind = InputSpec::Kind::kController;
  s.controller = reader(t, plant.nu());
  s.source = s.controller->estimate_source();
  return s;
}

}  // namespace

void register_inputs(InputRegistry& registry) {
  registry.add("none", "u = 0", read_none);
  registry.add("white", "u ~ N(0, std^2) each period, independent channels: std", read_white);
  registry.add("state_feedback",
               "u = -K x on the true state (source = \"plant\") or on an estimator's estimate "
               "(source = its name): K, source",
               read_state_feedback);
  registry.add("relay",
               "relay with dead zone, output i drives input i: u_i = -level if y_i > dead_zone, +level if "
               "y_i < -dead_zone, else 0; sees = \"true\" | \"measured\" | \"received\"",
               [](const sim::Table& t, const LinearPlant& p) { return read_controller(t, p, read_relay); });
  registry.add("pi",
               "discrete PI with reference weighting on one sensor output: u = kp (b r - y) + ki T sum(r - y); "
               "kp, ki, b, reference = {kind = \"square\", low, high, period} or {value}, feedback = "
               "\"received\" | \"measured\" | \"true\" | an estimator name, sensor, output, u_min, u_max",
               [](const sim::Table& t, const LinearPlant& p) { return read_controller(t, p, read_pi); });
}

}  // namespace ncosim::models
