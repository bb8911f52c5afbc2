// models/controller.h — every [input] kind is a controller: a plug-in of the input registry.
// A ControllerDesign is read once per scenario (shared read-only by every run); instantiate()
// makes the per-run controller, which keeps its own state (an integrator, a reference phase).
// At the control phase of period k the run hands it what a controller node could know
// (ControlContext) and it writes u[k]: one virtual call. Built in: none, white,
// state_feedback (models/input.cc), relay, pi (models/controller.cc). The loop timing is the
// input's `actuation_delay` (models/input.h).
#pragma once

#include <Eigen/Dense>
#include <cmath>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "config/config.h"
#include "config/keys.h"
#include "kernel/rng.h"
#include "models/sensor.h"

namespace ncosim::models {

struct ControlContext {
  std::int64_t k = 0;                  // period
  double t = 0.0;                      // k * period, seconds
  double period = 1.0;                 // seconds
  const Eigen::VectorXd* x = nullptr;  // true plant state x[k]
  // Per sensor: C x[k] (true output), the newest sample taken (C x + v, at its last sampling)
  // and the newest value received over the sensor's link (zero before the first arrival).
  const std::vector<Eigen::VectorXd>* true_output = nullptr;
  const std::vector<Eigen::VectorXd>* measured = nullptr;
  const std::vector<Eigen::VectorXd>* received = nullptr;
  const Eigen::VectorXd* estimate = nullptr;  // the source estimator's xhat[k|k] (nullptr: none)
  kernel::Rng* rng = nullptr;                 // the run's input stream (random inputs)
};

class Controller {
 public:
  virtual ~Controller() = default;
  // u[k] (nu entries, preallocated).
  virtual void compute(const ControlContext& ctx, Eigen::VectorXd& u) = 0;
  // The reference r[k] the controller tracks (for traces); NaN when it has none.
  virtual double reference(const ControlContext&) const { return std::nan(""); }
};

class ControllerDesign {
 public:
  virtual ~ControllerDesign() = default;
  // Resolves sensor references and checks sizes against the scenario's sensors; errors at
  // `t` (the [input] table). Called once by the scenario builder before any run.
  virtual void bind(const config::Table&, const std::vector<SensorSpec>&) {}
  // The estimator whose estimate the controller reads ("" for none) and the key that names it.
  virtual std::string estimate_source() const { return ""; }
  virtual const char* source_key() const { return "feedback"; }
  // u[k] depends on the plant (its state, outputs or an estimate): a closed loop.
  virtual bool closes_loop() const { return true; }
  // u[k] is computed from sensor outputs (ControlContext::true_output, measured, received):
  // the run fills them, re-centring is refused, and traces carry the `reference` column.
  virtual bool sees_outputs() const { return true; }
  virtual std::unique_ptr<Controller> instantiate() const = 0;
};

// Readers of the built-in controllers (registered by models/input.cc).
// The declared keys of the relay and PI inputs (config/keys.h), read by read_relay / read_pi.
const config::Keys& relay_keys();
const config::Keys& pi_keys();
std::shared_ptr<ControllerDesign> read_relay(const config::Table& t, Eigen::Index nu);
std::shared_ptr<ControllerDesign> read_pi(const config::Table& t, Eigen::Index nu);

// A periodic reference: square wave between `low` and `high` with period `period` seconds
// (`low` for the first half), or a constant.
struct Reference {
  double low = 0.0, high = 0.0, period = 0.0;  // period 0: constant `low`
  double at(double t) const;
};

}  // namespace ncosim::models
