// estimators/estimator.h — the estimator interface, its offline design, and the registry.
// An EstimatorDesign is built once per campaign from the scenario (gains, predicted
// covariances) and is shared read-only by every run and thread; instantiate() makes the
// per-run Estimator. Estimators see packets and the known input, never the true state.
#pragma once

#include <Eigen/Dense>
#include <cstdint>
#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "config/config.h"
#include "config/keys.h"
#include "config/registry.h"
#include "estimators/kalman_update.h"
#include "models/actuator.h"
#include "models/link.h"
#include "models/packet.h"
#include "models/plant.h"
#include "models/sensor.h"

namespace ncosim::est {

class JumpDesignAccess;  // estimators/jump_observer.h
class SodJumpDesign;     // estimators/sod_jump.h

// What an estimator may know of the scenario: the plant model, the sensors and the
// statistics of the links their packets cross.
struct SensorModel {
  models::SensorSpec spec;
  const models::Link* link = nullptr;  // nullptr: ideal link (delay 0, never lost)
  // P[a sample of this sensor arrives with delay d], d = 0..max_delay (design model).
  std::vector<double> delay_pmf(int max_delay) const;
};

// A controller-to-actuator channel: the estimators know what was sent, not what arrived.
struct ActuatorModel {
  models::ActuatorSpec spec;
  const models::Link* link = nullptr;  // nullptr: ideal (always delivered)
};

struct Model {
  models::LinearPlant plant;
  std::vector<SensorModel> sensors;
  std::vector<ActuatorModel> actuators;  // empty, or one per input channel
  double period = 1.0;                   // seconds
  Eigen::Index total_outputs() const;
  // Number of modes scored by mode_detection (0: none): the jump_linear plant's modes, or
  // 2^r with r actuators (delivery patterns, models/actuator.h numbering).
  int mode_count() const;
  // True when the plant or a sensor is nonlinear (plant.nonlinear or a sensor's spec.h set,
  // models/nonlinear.h); estimators that need a linear model refuse it.
  bool is_nonlinear() const;
};

// A packet as delivered (models/packet.h).
using Packet = models::Packet;

// What every estimator knows at the update of period k.
struct PeriodInput {
  const Eigen::VectorXd& u;  // input sent at k-1 (nu)
  // Known part of x[k] - A x[k-1] - Bw w[k-1] (n): Bu u + re-centring. With actuator links or a
  // jump_linear plant it is the nominal Bu times the *sent* u (what the estimators know).
  const Eigen::VectorXd& drive;
};

class Estimator {
 public:
  virtual ~Estimator() = default;
  // A packet delivered at period k (arrivals precede the update of period k). Returns the
  // number of its samples this estimator will use (in time and not seen before).
  virtual int on_packet(const Packet& packet, std::int64_t k) = 0;
  // The update of period k: predict with the known input (k > 0), then correct with what
  // arrived. Never throws; numerical trouble is reported by status().
  virtual void on_period(std::int64_t k, const PeriodInput& in) = 0;
  // xhat[k|k] (n): a view valid until the next call of on_period (no copy).
  using StateView = Eigen::Map<const Eigen::VectorXd>;
  virtual StateView state() const = 0;
  // The delay-extended estimate [xhat[k]; xhat[k-1]; ...] or nullptr when it has none.
  virtual const Eigen::VectorXd* extended() const { return nullptr; }
  // The filter's own error covariance of extended() (or of state()), when it keeps one.
  virtual const Eigen::MatrixXd* covariance() const { return nullptr; }
  // Mode estimators: the estimated mode of the transition into the current period
  // (theta[k-1] after the update of period k, Moayedi et al. eq. 16), in the scenario's mode
  // numbering; nullopt when the estimator has no mode or no estimate yet.
  virtual std::optional<int> mode() const { return std::nullopt; }
  // "ok" or why the run's estimate cannot be trusted (e.g. "numerical_failure").
  virtual std::string status() const { return "ok"; }
  // Work and packet bookkeeping of the run so far, for estimators whose cost varies from
  // period to period (kalman_buffer); nullptr for the others.
  struct RunCounters {
    double flops = 0.0;        // FLOPs spent since period 0 (flops_per_period's formula per step)
    double flops_worst = 0.0;  // the most spent in one period
    std::int64_t periods = 0;  // updates done
    std::int64_t late = 0;     // samples that arrived too late for the buffer: discarded
    std::int64_t duplicates = 0;  // samples that arrived again: ignored
  };
  virtual const RunCounters* counters() const { return nullptr; }
  // Filters whose update whitens an innovation nu with its own covariance S: the normalised
  // innovations of every update since period 0 (kalman::Innovations), for the consistency check
  // (NIS); nullptr for the others.
  using Innovations = kalman::Innovations;
  virtual const Innovations* innovations() const { return nullptr; }
};

// Offline part, reported in design.json.
struct DesignReport {
  std::string method;  // e.g. "iterative", "none"
  double design_seconds = 0.0;
  std::optional<long> stored_gains;
  std::optional<double> predicted_mse;      // tr of the plant-state block of Pt
  std::optional<double> predicted_mse_ext;  // tr(Pt) over the extended state
  std::optional<bool> stable;
  std::string status = "ok";                        // "ok" or why the design failed
  nlohmann::json extra = nlohmann::json::object();  // kind-specific fields
};

class EstimatorDesign {
 public:
  virtual ~EstimatorDesign() = default;
  virtual std::unique_ptr<Estimator> instantiate() const = 0;
  virtual const DesignReport& report() const = 0;
  // FLOPs per period by the paper's formula (upper bound of one update).
  virtual std::optional<double> flops_per_period() const = 0;
  // Size of the delay-extended state (n (dbar+1)), or 0 when it has none.
  virtual Eigen::Index extended_size() const { return 0; }
  // True when the design's model is Dolz et al.'s fictitious sensors: each (sensor, delay)
  // sample arrives independently with its marginal probability, one sample per sensor and
  // period. summary.csv's model_check then also notes sensors that sample every few periods
  // (the design treats them as a rate), physical packets that can arrive with one of several
  // delays (the design assumes an independent copy per delay) and buffered re-sends that carry
  // the same noise (resend_noise = "same"; the design assumes fresh noise). Default: false.
  virtual bool models_independent_fictitious_sensors() const { return false; }

  // Capabilities: what tools ask a design instead of its kind's name (nullptr / false: none).
  // A minimum-variance (Kalman) filter: the default reference of paired comparisons (the first
  // such estimator; sim/analysis/paired.cc). Default: false.
  virtual bool is_kalman_reference() const { return false; }
  // Read access for the embedded C export (`ncosim design --export-c`, estimators/export_c.h).
  virtual const JumpDesignAccess* c_export() const { return nullptr; }
  // The send-on-delta threshold co-design (`ncosim codesign`, sim/cmd/codesign.cc).
  virtual const SodJumpDesign* sod_codesign() const { return nullptr; }
};

// A design's cost, estimated by its kind BEFORE designing, from its table and the model:
// peak memory in bytes and work in floating-point operations. sim/scenario/resource_limits.cc
// compares them with
// --max-memory / --max-work, refuses a design beyond them and notes a large one before it starts.
struct DesignCost {
  double bytes = 0.0;
  double flops = 0.0;
  // What drives the size, for the messages ("its size is driven by ..."); empty: the plant's
  // state driver (sim::state_driver, e.g. "plant.A (60 plant states)").
  std::string driver;
};

// The kind's estimate. `raw` is the estimator's TOML table, read without marking keys known (the
// kind's reader validates them: use peek_integer); `t` names keys in messages (t.key_path);
// `state_driver` is the plant's state driver. Must be cheap (no design work) and must not throw
// for values the reader would reject.
using CostEstimate = std::function<DesignCost(const config::Table& t, const toml::table& raw,
                                              const Model& model, const std::string& state_driver)>;

// The estimate of a kind that declares none (an extension registered with add(name, help,
// factory)): a Riccati or Lyapunov iteration on the plant state, 16 n x n matrices and 200
// products of them (16 * 8 n^2 bytes, 400 n^3 flops).
DesignCost generic_design_cost(const Model& model);

// The integer key `key` (the kind's declaration) of `raw`, read without marking it known: the
// declared default when absent or not an integer (the reader reports that; the declared minimum,
// else 0, for a key without one), clamped to the declared range.
std::int64_t peek_integer(const toml::table& raw, const config::Key& key);
// The string or choice key `key` of `raw`, read likewise: the declared default ("" without one)
// when absent or not a string.
std::string peek_string(const toml::table& raw, const config::Key& key);

// The estimator registry: config::Registry's name, help and factory, plus an optional cost estimate
// per kind, declared with the kind in its own file: registry.add(name, help, factory, cost).
class EstimatorRegistry : public config::Registry<std::unique_ptr<EstimatorDesign>, const Model&> {
 public:
  using Base = config::Registry<std::unique_ptr<EstimatorDesign>, const Model&>;
  using Base::add;
  void add(std::string name, std::string help, Factory factory, CostEstimate cost) {
    costs_.emplace_back(name, std::move(cost));
    Base::add(std::move(name), std::move(help), std::move(factory));
  }
  // A kind that declares its keys (config/keys.h) and estimates its design's cost.
  void add(std::string name, std::string help, config::Keys keys, Factory factory,
           CostEstimate cost) {
    costs_.emplace_back(name, std::move(cost));
    Base::add(std::move(name), std::move(help), std::move(keys), std::move(factory));
  }
  // The estimate of kind `kind` (generic_design_cost when it declared none).
  DesignCost cost(std::string_view kind, const config::Table& t, const toml::table& raw,
                  const Model& model, const std::string& state_driver) const;
  // Kinds that accept a nonlinear model (Model::is_nonlinear(); models/nonlinear.h). Every other
  // kind needs a linear one: the scenario reader refuses it on a nonlinear plant or sensor.
  void accept_nonlinear(std::string name) { nonlinear_.push_back(std::move(name)); }
  bool accepts_nonlinear(std::string_view kind) const {
    for (const auto& n : nonlinear_)
      if (n == kind) return true;
    return false;
  }

 private:
  std::vector<std::pair<std::string, CostEstimate>> costs_;
  std::vector<std::string> nonlinear_;
};
void register_estimators(EstimatorRegistry& registry);

// Keys every kind declares with its own (config/keys.h): xhat0 (default: the plant's x0) and P0
// (default 0), read by read_initial (the mode estimators declare their own, mode_model.h).
struct InitialEstimate {
  Eigen::VectorXd xhat0;
  Eigen::MatrixXd P0;
};
const config::Keys& initial_keys();
InitialEstimate read_initial(const config::Table& t, const Model& model);

// `max_delay` (dbar), 0..62 periods, without a default (a kind adds or_default / optional).
config::Key max_delay_key();

}  // namespace ncosim::est
