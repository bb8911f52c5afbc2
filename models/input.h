// models/input.h — the plant input u[k], computed by the [input] kind's controller
// (models/controller.h): none, white noise, state feedback u = -K xhat (on the true state,
// source = "plant", or on a named estimator's estimate), relay, pi, or a registered kind.
// Every kind takes `actuation_delay`: u[k] computed
// at period k acts on x[k+1+actuation_delay] (0: x[k+1] = A x[k] + Bu u[k] + ...; 1: the
// paper form x[k+1] = A x[k] + Bu u[k-1] + ...).
#pragma once

#include <Eigen/Dense>
#include <memory>
#include <string>

#include "config/config.h"
#include "config/registry.h"
#include "models/controller.h"
#include "models/plant.h"

namespace ncosim::models {

// The controller of kind "none" (u = 0): the input of a scenario without [input].
std::shared_ptr<ControllerDesign> no_input();

struct InputSpec {
  std::shared_ptr<ControllerDesign> controller = no_input();
  std::string source;       // the estimator whose estimate the controller reads ("": none)
  int source_index = -1;    // resolved estimator index (-1: none)
  int actuation_delay = 0;  // periods between computing u[k] and its first effect beyond x[k+1]
};

using InputRegistry = config::Registry<InputSpec, const LinearPlant&>;
void register_inputs(InputRegistry& registry);

}  // namespace ncosim::models
