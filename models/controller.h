// models/controller.h — controllers as plug-ins of the [input] registry. A ControllerDesign is
// read once per scenario (shared read-only by every run); instantiate() makes the per-run
// controller, which keeps its own state (an integrator, a reference phase). At the control
// phase of period k the simulator hands it what a controller node could know (ControlContext)
// and it writes u[k]. The loop timing is the input's `actuation_delay` (sim/campaign.cc).
#pragma once

#include <Eigen/Dense>
#include <cmath>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "config/config.h"
#include "models/sensor.h"

namespace ncosim::models {

struct ControlContext {
  std::int64_t k = 0;   // period
  double t = 0.0;       // k * period, seconds
  double period = 1.0;  // seconds
  const Eigen::VectorXd* x = nullptr;  // true plant state x[k]
  // Per sensor: C x[k] (true output), the newest sample taken (C x + v, at its last sampling)
  // and the newest value received over the sensor's link (zero before the first arrival).
  const std::vector<Eigen::VectorXd>* true_output = nullptr;
  const std::vector<Eigen::VectorXd>* measured = nullptr;
  const std::vector<Eigen::VectorXd>* received = nullptr;
  const Eigen::VectorXd* estimate = nullptr;  // the source estimator's xhat[k|k] (nullptr: none)
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
  virtual void bind(const sim::Table& t, const std::vector<SensorSpec>& sensors) = 0;
  // The estimator whose estimate the controller reads ("" for none).
  virtual std::string estimate_source() const { return ""; }
  virtual std::unique_ptr<Controller> instantiate() const = 0;
};

// Readers of the built-in controllers (registered by models/input.cc).
std::shared_ptr<ControllerDesign> read_relay(const sim::Table& t, Eigen::Index nu);
std::shared_ptr<ControllerDesign> read_pi(const sim::Table& t, Eigen::Index nu);

// A periodic reference: square wave between `low` and `high` with period `period` seconds
// (`low` for the first half), or a constant.
struct Reference {
  double low = 0.0, high = 0.0, period = 0.0;  // period 0: constant `low`
  double at(double t) const;
};

}  // namespace ncosim::models
