// estimators/mode_model.h — the Markov jump linear model shared by the mode estimators (imm,
// mode_io, mode_ss). Two sources of modes:
// - actuator links (Moayedi et al., eqs. 4-14): mode = delivery pattern of the r actuator
//   links (models/actuator.h numbering); "hold" channels put the last applied input in the
//   state, z = [x; u_applied(k-1) of the hold channels] (eq. 14, per channel), "zero" channels
//   apply Gamma(theta) u (eq. 9); the transition matrix is the Kronecker product of the links'
//   on-time chains (eq. 26 with the second factor conditioned on its own link);
// - a jump_linear plant: mode j has its own A, Bu, Bw W Bw'.
// Every mode's input is [u sent at k-1; known re-centring drive] (B_j has nu + n columns).
// Bad keys raise ScenarioError from read_mode_setup().
#pragma once

#include <Eigen/Dense>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "estimators/delay_window.h"
#include "estimators/estimator.h"
#include "estimators/extended_model.h"
#include "estimators/kalman_update.h"

namespace ncosim::est {

struct ModeModel {
  Eigen::Index n = 0;                    // plant state
  Eigen::Index na = 0;                   // estimator state: n + hold channels
  Eigen::Index nu = 0;                   // inputs sent
  Eigen::Index nue = 0;                  // nu + n: inputs and the known re-centring drive
  Eigen::Index m = 0;                    // stacked sensor outputs
  int channels = 0;                      // actuators (0 for a jump_linear plant)
  std::vector<int> hold;                 // hold channels, in order (their u_applied is in z)
  std::vector<Eigen::MatrixXd> A, B, Q;  // per mode: na x na, na x nue, na x na
  Eigen::MatrixXd C, R;                  // m x na (plant C padded), m x m block-diagonal
  Eigen::MatrixXd Bu;                    // nominal plant Bu (n x nu), for the re-centring drive
  Eigen::MatrixXd transition;            // s x s, row-stochastic
  Eigen::VectorXd stationary;            // its stationary law
  ExtendedModel ext0;                    // the sensors without delay (packet bookkeeping)
  int modes() const { return static_cast<int>(A.size()); }
};

// What every mode estimator reads: model, xhat0 and P0 (of size n, padded with the actuators'
// u0 and zero covariance, or of size na), mode_prior, transition (optional override), use_y0.
struct ModeSetup {
  ModeModel model;
  Eigen::VectorXd x0;   // na
  Eigen::MatrixXd P0;   // na x na
  Eigen::VectorXd mu0;  // s: p(theta[-1] = j | Y0)
  bool use_y0 = true;   // correct with y[0] at period 0 (xhat0 is the prior of period 0)
};
// The keys of every mode estimator (imm, mode_ss; mode_io adds startup): xhat0, P0 (over the
// augmented state), mode_prior, transition, use_y0.
const config::Keys& mode_keys();
ModeSetup read_mode_setup(const config::KeyReader& r, const Model& model);

// Packets of the current period (delay 0) as a stacked measurement and a 0/1 row mask.
class CurrentMeasurement {
 public:
  explicit CurrentMeasurement(const ExtendedModel& ext0);
  int accept(const Packet& p, std::int64_t k) { return window_.accept(p, k); }
  // Moves to period k and fills mask() for what arrived; returns the rows delivered.
  Eigen::Index take(std::int64_t k);
  const Eigen::VectorXd& values() const { return window_.values(); }
  const Eigen::VectorXd& mask() const { return mask_; }

 private:
  const ExtendedModel* ext_;
  DelayWindow window_;
  Eigen::VectorXd mask_;
};

// The single Kalman filter of Algorithms 1 and 2 (Moayedi et al. eq. 18) on the mode model,
// with the rows of the delivered sensors. select() picks the rows; predict() with the mode
// chosen; update() corrects (Cholesky; a failure keeps the prediction and sets failed()).
class ModeKalman {
 public:
  ModeKalman(const ModeModel& mm, const Eigen::VectorXd& x0, const Eigen::MatrixXd& P0);
  // Selects the rows with mask != 0; returns their number.
  Eigen::Index select(const Eigen::VectorXd& mask);
  // Log-likelihood of the selected rows of y under the one-step prediction of mode j from the
  // current (x, P): yhat = C (A_j x + B_j u), Sigma = C (A_j P A_j' + Q_j) C' + R (eqs. 24-25).
  // Keeps that prediction (for predict_from_last of the chosen mode, see keep()).
  double predicted_loglik(int j, const Eigen::VectorXd& u, const Eigen::VectorXd& y);
  void predict(int j, const Eigen::VectorXd& u);
  void update(const Eigen::VectorXd& y);
  const Eigen::VectorXd& x() const { return x_; }
  const Eigen::MatrixXd& P() const { return P_; }
  bool failed() const { return failed_; }
  Eigen::Index rows() const { return used_; }
  // The selected rows of y into out(0 .. rows()-1) (valid after select()).
  void selected(const Eigen::VectorXd& y, Eigen::VectorXd& out) const;
  // The selected rows, in order.
  const std::vector<Eigen::Index>& selected_rows() const { return rows_; }

 private:
  void load(const Eigen::VectorXd& y);  // the selected rows of y into the workspace

  const ModeModel* mm_;
  Eigen::VectorXd x_, xp_;
  Eigen::MatrixXd P_, Pp_;
  kalman::Workspace ws_;  // selected rows of C and R, the update's factors
  std::vector<Eigen::Index> rows_;
  Eigen::Index used_ = 0;
  bool failed_ = false;
};

// Log-domain Bayes step p_j ∝ prior_j exp(loglik_j); returns false (p = prior) when no term
// is finite. Shared by mode_io and mode_ss (eq. 19).
bool bayes_log(const Eigen::VectorXd& prior, const Eigen::VectorXd& loglik, Eigen::VectorXd& p);

// FLOPs of one Kalman predict + update with na states, nue inputs and m outputs (counted as
// in results/README.md).
double kalman_flops(double na, double nue, double m);

}  // namespace ncosim::est
