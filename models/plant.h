// models/plant.h — linear plants: x[k+1] = A x[k] + Bu u[k] + Bw w[k], w ~ N(0, W).
// `lti` is given in discrete time; `lti_continuous` is discretised exactly at the control
// period: zero-order hold for the input, Van Loan (1978) for the noise covariance.
// Bad parameters raise ScenarioError from the readers.
#pragma once

#include <Eigen/Dense>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "config/config.h"
#include "config/registry.h"

namespace ncosim::models {

struct LinearPlant;
class NonlinearDynamics;  // models/nonlinear.h
class PlantProcess;
struct PlantRun;
// Makes the per-run process of a plant (models/plant_process.h).
using PlantProcessFactory =
    std::function<std::unique_ptr<PlantProcess>(const LinearPlant&, const PlantRun&)>;

// One mode of a jump_linear plant: its own A, Bu, Bw, W.
struct PlantMode {
  Eigen::MatrixXd A, Bu, Bw, W;
};

struct LinearPlant {
  Eigen::MatrixXd A;   // n x n
  Eigen::MatrixXd Bu;  // n x nu (nu may be 0)
  Eigen::MatrixXd Bw;  // n x nw
  Eigen::MatrixXd W;   // nw x nw, symmetric PSD
  Eigen::VectorXd x0;  // n
  // jump_linear only (empty otherwise): x[k+1] = A_m Bu_m ... with m = theta[k], a Markov chain
  // with mode_transition(i, j) = P(theta[k] = j | theta[k-1] = i) and theta[0] ~ mode_initial.
  // A, Bu, Bw, W above are then the nominal (base) matrices that the modes override.
  std::vector<PlantMode> modes;
  Eigen::MatrixXd mode_transition;
  Eigen::VectorXd mode_initial;
  // The plant's own output matrix when its kind defines one (transfer_function: y = C x),
  // which sensors use with C = "output"; empty otherwise.
  Eigen::MatrixXd C_out;
  // Non-empty when the true state is not simulated from this model but is the motion of a
  // vehicle of the scenario's mobility source ([sumo]): the key of the plant table that names
  // the vehicle. The matrices are then the estimators' design model only (sumo_vehicle).
  std::string vehicle_key;
  // The per-run process of the true plant, set by the kind's reader (empty: the linear process;
  // jump_linear and sumo_vehicle set theirs: models/plant_process.h).
  PlantProcessFactory process;
  // Non-null for a nonlinear plant (models/nonlinear.h): x[k+1] = f(x[k], u[k], k) + Bw w[k]; A and
  // Bu are then f's Jacobians at (x0, 0, 0), and the kind's reader sets `process` to step f.
  std::shared_ptr<const NonlinearDynamics> nonlinear;
  Eigen::Index n() const { return A.rows(); }
  Eigen::Index nu() const { return Bu.cols(); }
  Eigen::Index nw() const { return Bw.cols(); }
  double spectral_radius() const;
};

// Exact discretisation of dx = (Ac x + Bc u) dt + Gc dβ, E[dβ dβ'] = Wc dt, at period T:
// A = e^{Ac T}, Bu = ∫_0^T e^{Ac s} ds Bc, and W = ∫_0^T e^{Ac s} Gc Wc Gc' e^{Ac' s} ds
// (Van Loan's block exponential), returned with Bw = I.
LinearPlant discretise(const Eigen::MatrixXd& Ac, const Eigen::MatrixXd& Bc,
                       const Eigen::MatrixXd& Gc, const Eigen::MatrixXd& Wc, double period);

// A deterministic disturbance added to the Gaussian w (per channel, nw entries):
// w_det[k] = offset + sum_j amplitude_j sin(omega_j k + phase_j), k the period index.
struct Disturbance {
  struct Sine {
    Eigen::VectorXd amplitude;
    double omega = 0.0;  // rad per period
    double phase = 0.0;  // rad
  };
  Eigen::VectorXd offset;  // empty: no deterministic part
  std::vector<Sine> sines;
  bool empty() const { return offset.size() == 0; }
  void at(std::int64_t k, Eigen::VectorXd& out) const;  // out += w_det[k]
};
// Reads the optional `disturbance` sub-table of [plant] (offset, [[sine]] amplitude, omega, phase).
Disturbance read_disturbance(const config::Table& plant_table, Eigen::Index nw);

// Continuous transfer function num(s)/den(s) e^{-dead_time s} (descending powers, strictly
// proper), realised in controllable canonical form and discretised by zero-order hold at
// `period`, the dead time as extra input-delay states (a fractional part split between two
// held inputs). Input disturbance: Bw = the undelayed ZOH input matrix (one channel).
LinearPlant discretise_transfer_function(const std::vector<double>& num,
                                         const std::vector<double>& den, double dead_time,
                                         double period);

// Symmetric square root S (S S' = M) of a PSD matrix by eigen-decomposition.
Eigen::MatrixXd psd_sqrt(const Eigen::MatrixXd& M);

// Stationary law of a row-stochastic matrix (least squares on [T' - I; 1'] pi = [0; 1]);
// defined in link.cc beside the Markov links that also use it.
Eigen::VectorXd stationary_law(const Eigen::MatrixXd& transition);

using PlantRegistry = config::Registry<LinearPlant, double /*period seconds*/>;
void register_plants(PlantRegistry& registry);

}  // namespace ncosim::models
