// models/input.h — the plant input u[k]: none, white noise, or state feedback u = -K xhat
// (on the true state, source = "plant", or on a named estimator's estimate).
#pragma once

#include <Eigen/Dense>
#include <string>

#include "models/plant.h"
#include "sim/config.h"
#include "sim/registry.h"

namespace ncosim::models {

struct InputSpec {
  enum class Kind { kNone, kWhite, kStateFeedback };
  Kind kind = Kind::kNone;
  Eigen::VectorXd std;   // white: per-channel standard deviation (nu)
  Eigen::MatrixXd K;     // state_feedback: nu x n
  std::string source;    // state_feedback: "plant" or an estimator name
  int source_index = -1; // resolved estimator index (-1: plant)
};

using InputRegistry = sim::Registry<InputSpec, const LinearPlant&>;
void register_inputs(InputRegistry& registry);

}  // namespace ncosim::models
