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

}  // namespace

void register_inputs(InputRegistry& registry) {
  registry.add("none", "u = 0", read_none);
  registry.add("white", "u ~ N(0, std^2) each period, independent channels: std", read_white);
  registry.add("state_feedback",
               "u = -K x on the true state (source = \"plant\") or on an estimator's estimate "
               "(source = its name): K, source",
               read_state_feedback);
}

}  // namespace ncosim::models
