// estimators/design/sod_design.h — H-infinity design of the send-on-delta jump observer
// x^[t] = x^[t-] + L(alpha[t]) (m[t] - C x^[t-]) (the send-on-delta co-design paper, section 3),
// by LMIs on CSDP (lmi/lmi.h), and the greedy threshold co-design of section 4.
//   deterministic: LMI (11) for every pair of sending patterns (j, k), P_j per pattern;
//   stochastic:    LMI (20) with one P, imposed at the 2^ns vertices of the probability box
//                  beta_i in [beta'_i, 1] (exact: Psi is multi-affine in beta),
//                  blocks of zero-probability patterns dropped (Psi >= 0 reading), or only at
//                  beta = beta' (the variant that may be the paper's; labelled "lower_vertex").
// Patterns are over sensors (a sensor sends all its outputs); the paper's example has one output
// per sensor. The bound is gamma_w ||w||^2 + sum gamma_v_i ||v_i||^2 + sum gamma_d_i sigma^2_d_i
// >= ||z~||^2_RMS (guaranteed under the design's assumptions).
#pragma once

#include <Eigen/Dense>
#include <functional>
#include <string>
#include <vector>

#include "lmi/lmi.h"

namespace ncosim::est::sod {

struct SodSystem {
  Eigen::MatrixXd A, Bw, C, Cz;           // C stacked over the sensors' outputs
  std::vector<Eigen::Index> sensor_rows;  // first stacked row of each sensor, and the end
  double w_rms = 0.0;                     // ||w||_RMS (the whole vector)
  Eigen::VectorXd v_rms;                  // ||v_i||_RMS per output
  // Per sensor: send-on-delta (its held value is a measurement with virtual noise) or periodic
  // (a held value is stale: in the patterns where it did not deliver, its gain columns are 0).
  // Empty: every sensor is send-on-delta.
  std::vector<bool> send_on_delta;
  Eigen::Index ns() const { return static_cast<Eigen::Index>(sensor_rows.size()) - 1; }
  Eigen::Index ny() const { return C.rows(); }
  // eta_j: diag with 1 on the outputs of the sensors in pattern j (bit s = sensor s sent).
  Eigen::VectorXd eta(unsigned j) const;
};

enum class Approach { kDeterministic, kStochastic };
enum class Vertices { kAll, kLower };  // stochastic: robust (all vertices) or beta = beta' only

struct SodDesignSpec {
  Approach approach = Approach::kDeterministic;
  bool jump = true;  // false: one constant gain L (Q_j = Q, X_j = X)
  Vertices vertices = Vertices::kAll;
  Eigen::VectorXd sigma2_delta;  // virtual-noise variance bound per output
  Eigen::VectorXd beta_lower;    // per SENSOR, stochastic only
  double margin = 1e-7;          // strictness margin of the LMIs
};

struct SodDesignResult {
  bool ok = false;
  std::string status = "ok";           // "ok" or the solver status
  std::string message;                 // why, when not ok (lmi::Solution::message)
  double bound = 0.0;                  // guaranteed ||z~||^2_RMS
  std::vector<Eigen::MatrixXd> gains;  // L_j, j = 0 .. 2^ns - 1 (all equal for a constant gain)
  double gamma_w = 0.0;
  Eigen::VectorXd gamma_v, gamma_delta;
  std::vector<Eigen::MatrixXd> Q, X, P;  // the solved variables (P: one per pattern, or one)
  int lmis = 0;                          // LMI blocks in the SDP
  lmi::SdpSize size;
  double seconds = 0.0;  // solver wall time
};

SodDesignResult design_sod(const SodSystem& sys, const SodDesignSpec& spec);

// z~0 of Remark 8: the bound with every measurement every period (j = k = all, no delta).
SodDesignResult design_all_measurements(const SodSystem& sys);

// Psi(beta) of (20) evaluated at the solved variables of a stochastic design (every pattern
// block kept, zero-probability blocks are zero): for the vertex-exactness check.
Eigen::MatrixXd psi_at(const SodSystem& sys, const SodDesignResult& r, const Eigen::VectorXd& beta,
                       const Eigen::VectorXd& sigma2_unused = {});

// Scenario probabilities p_j(beta) of (18)-(19) (beta per sensor).
std::vector<double> pattern_probabilities(const Eigen::VectorXd& beta);

// ---- co-design (section 4, greedy) ----------------------------------------------------------

enum class Assumption { kUniform, kGaussian };

struct CodesignSpec {
  Approach approach = Approach::kStochastic;
  bool jump = true;
  Vertices vertices = Vertices::kAll;
  Assumption assumption = Assumption::kUniform;
  Eigen::VectorXd r;           // uniform range (28) or Gaussian sigma, per output (= per sensor)
  Eigen::VectorXd g;           // deterministic cost weights (35) (default r)
  double sigma2_factor = 1.0;  // deterministic: sigma^2_delta = factor * Delta^2 (1 or 1/3)
  double target = 0.0;         // z~rms (the bound to meet)
  double epsilon = 0.01;       // cost step per iteration
  bool relative_step = false;  // J_k = J_{k-1} (1 - epsilon) instead of J_{k-1} - epsilon
  Eigen::VectorXd delta0;      // starting thresholds
  int max_iterations = 10000;
};

struct CodesignStep {
  int iteration = 0;
  Eigen::VectorXd delta;
  double cost = 0.0, bound = 0.0;
};

struct CodesignResult {
  Eigen::VectorXd delta;   // the last accepted thresholds
  SodDesignResult design;  // the design at them
  double cost = 0.0;
  int iterations = 0;
  int lmi_problems = 0;      // SDPs solved
  double lmi_seconds = 0.0;  // their solver time
  double seconds = 0.0;      // whole co-design wall time
  std::vector<CodesignStep> path;
  std::string status = "ok";  // "ok", "start_infeasible" (delta0 misses the target)
};

// Per-threshold sigma^2_delta and beta' (per sensor) of a co-design spec.
void codesign_bounds(const CodesignSpec& spec, const Eigen::VectorXd& delta,
                     Eigen::VectorXd& sigma2, Eigen::VectorXd& beta);
double codesign_cost(const CodesignSpec& spec, const Eigen::VectorXd& delta);

CodesignResult codesign(const SodSystem& sys, const CodesignSpec& spec,
                        const std::function<void(const CodesignStep&)>& progress = {});

}  // namespace ncosim::est::sod
