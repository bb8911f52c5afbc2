// models/input.h — the plant input u[k]: none, white noise, or state feedback u = -K xhat
// (on the true state, source = "plant", or on a named estimator's estimate), or a controller
// plug-in (models/controller.h: relay, pi). Every kind takes `actuation_delay`: u[k] computed
// at period k acts on x[k+1+actuation_delay] (0: x[k+1] = A x[k] + Bu u[k] + ...; 1: the
// paper form x[k+1] = A x[k] + Bu u[k-1] + ...).
#pragma once

#include <Eigen/Dense>
#include <string>

#include <memory>

#include "config/config.h"
#include "config/registry.h"
#include "models/controller.h"
#include "models/plant.h"

namespace ncosim::models {

struct InputSpec {
  enum class Kind { kNone, kWhite, kStateFeedback, kController };
  Kind kind = Kind::kNone;
  Eigen::VectorXd std;   // white: per-channel standard deviation (nu)
  Eigen::MatrixXd K;     // state_feedback: nu x n
  std::string source;    // state_feedback: "plant" or an estimator name
  int source_index = -1; // resolved estimator index (-1: plant)
  std::shared_ptr<ControllerDesign> controller;  // kController
  int actuation_delay = 0;  // periods between computing u[k] and its first effect beyond x[k+1]
};

using InputRegistry = sim::Registry<InputSpec, const LinearPlant&>;
void register_inputs(InputRegistry& registry);

}  // namespace ncosim::models
