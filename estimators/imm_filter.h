// estimators/imm_filter.h — numerical core of the interacting multiple model (IMM) filter.
#pragma once

#include <Eigen/Dense>
#include <vector>

#include "estimators/kalman_update.h"

namespace ncosim::est {

// One mode of a jump linear system: x(k+1) = F x(k) + B u(k) + w, w ~ N(0, Q);
// z(k) = H x(k) + v, v ~ N(0, R). B may have 0 columns.
struct ImmMode {
  Eigen::MatrixXd F;  // n x n
  Eigen::MatrixXd B;  // n x nu
  Eigen::MatrixXd Q;  // n x n
  Eigen::MatrixXd H;  // m x n
  Eigen::MatrixXd R;  // m x m
};

enum class ImmStatus {
  kOk,
  kInnovationNotPositiveDefinite,  // Cholesky of some S_j failed: that update was skipped
  kNonFiniteLikelihood,            // innovation or log-likelihoods not finite: update skipped
};

// IMM filter for a jump linear system with s modes and Markov mode transitions
// M(i, j) = P(mode j at k | mode i at k-1), one Kalman filter per mode
// (Bar-Shalom, Li & Kirubarajan 2001, "Estimation with Applications to Tracking and
// Navigation", section 11.6.6, steps 1-5 of one cycle). predict(): mixing
//   cbar_j = sum_i M(i,j) mu_i,  mu_{i|j} = M(i,j) mu_i / cbar_j,
//   x0_j = sum_i mu_{i|j} x_i,   P0_j = sum_i mu_{i|j} (P_i + (x_i - x0_j)(x_i - x0_j)'),
// then the mode-matched prediction x_j = F_j x0_j + B_j u, P_j = F_j P0_j F_j' + Q_j.
// update(z): mode-matched Kalman updates, likelihoods Lambda_j = N(z - H_j x_j; 0, S_j)
// (Cholesky; mode probabilities mu_j = cbar_j Lambda_j / sum_i cbar_i Lambda_i normalised in
// the log domain, so likelihoods that underflow to 0 still give a proper mu), and the
// combination x = sum_j mu_j x_j, P = sum_j mu_j (P_j + (x_j - x)(x_j - x)').
// mu() is P(mode at k | measurements so far): cbar right after predict(), so x() and P() after
// predict() are the prior combined with cbar (not filterpy's x_prior, which uses the previous
// mu), and a second update() without predict() is a sequential measurement of the same period.
// A missing measurement (skip_update(), or an all-zero row mask) leaves the priors and
// mu = cbar (likelihoods 1). A measurement may carry only some of its rows (row mask).
// Buffers are allocated at construction and steps do not allocate (checked with
// EIGEN_RUNTIME_NO_MALLOC up to n = 64; beyond that Eigen's matrix-product workspace leaves the
// stack). Never throws on a step: a non-positive-definite S_j or a non-finite likelihood skips
// that update for every mode (priors kept, mu = cbar) and is reported by status() (sticky) and
// last_update_applied(); the estimate stays finite.
class ImmFilter {
 public:
  // All modes share n, m and nu; `transition` is s x s, row-stochastic; mu0 sums to 1. Every
  // mode filter starts at (x0, P0). Inconsistent sizes are programmer errors (abort).
  ImmFilter(std::vector<ImmMode> modes, const Eigen::MatrixXd& transition,
            const Eigen::VectorXd& x0, const Eigen::MatrixXd& P0, const Eigen::VectorXd& mu0);

  // Restarts every mode filter at (x0, P0) with mode probabilities mu0; clears the status.
  void reset(const Eigen::VectorXd& x0, const Eigen::MatrixXd& P0, const Eigen::VectorXd& mu0);

  // Mixing and mode-matched prediction with the known input u (nu rows; empty if nu = 0).
  void predict(const Eigen::Ref<const Eigen::VectorXd>& u);
  void predict();
  // Update with every row of z (m).
  void update(const Eigen::Ref<const Eigen::VectorXd>& z);
  // Update with the rows r of z for which row_mask(r) != 0 (the 0/1 convention of
  // ExtendedModel::row_mask); the other rows of z are not read. No row: skip_update().
  void update(const Eigen::Ref<const Eigen::VectorXd>& z,
              const Eigen::Ref<const Eigen::VectorXd>& row_mask);
  // Missing measurement: posteriors are the priors, likelihoods 1, mu = cbar.
  void skip_update();

  int modes() const { return static_cast<int>(modes_.size()); }
  Eigen::Index state_size() const { return n_; }
  Eigen::Index measurement_size() const { return m_; }

  const Eigen::VectorXd& mode_x(int j) const { return x_[static_cast<std::size_t>(j)]; }
  const Eigen::MatrixXd& mode_P(int j) const { return P_[static_cast<std::size_t>(j)]; }
  // Lambda_j of the last update (1 if skipped or missing); may underflow to 0, see below.
  double likelihood(int j) const;
  // log Lambda_j of the last update (0 if skipped or missing); finite unless skipped.
  double log_likelihood(int j) const { return loglik_(j); }
  const Eigen::VectorXd& cbar() const { return cbar_; }
  const Eigen::VectorXd& mu() const { return mu_; }
  const Eigen::VectorXd& x() const { return x_comb_; }
  // Combined on first use after a step (the estimate x() is combined eagerly).
  const Eigen::MatrixXd& P() const;
  int most_probable_mode() const;

  // First failure since construction or reset() (kOk if none).
  ImmStatus status() const { return status_; }
  // Whether the last update (not skip_update) corrected the estimates.
  bool last_update_applied() const { return last_applied_; }

 private:
  void mix();
  void combine();
  void combine_covariance() const;
  void select_rows(const Eigen::Ref<const Eigen::VectorXd>* row_mask);
  void correct(const Eigen::Ref<const Eigen::VectorXd>& z);
  void fail(ImmStatus why);

  std::vector<ImmMode> modes_;
  Eigen::MatrixXd M_;  // transition matrix (s x s)
  Eigen::Index n_ = 0, m_ = 0, nu_ = 0;

  // Per-mode state and workspace (index j = mode).
  std::vector<Eigen::VectorXd> x_, x_mix_;
  std::vector<Eigen::MatrixXd> P_, P_mix_;
  std::vector<kalman::Workspace> ws_;  // mode j's prediction scratch and update factors
  Eigen::VectorXd loglik_, cbar_, mu_, x_comb_, log_mu_;
  mutable Eigen::VectorXd d_, dw_;
  mutable Eigen::MatrixXd P_comb_;
  mutable bool p_stale_ = true;
  Eigen::MatrixXd omega_;  // omega_(i, j) = mu_{i|j}
  // Selected measurement rows.
  std::vector<Eigen::Index> rows_;
  Eigen::Index m_used_ = 0;

  ImmStatus status_ = ImmStatus::kOk;
  bool last_applied_ = false;
};

}  // namespace ncosim::est
