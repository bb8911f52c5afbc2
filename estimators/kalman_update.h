// estimators/kalman_update.h — the one Kalman kernel of every Kalman-type estimator
// (kalman_extended, kalman_buffer, sod_kalman, the mode filters of mode_io / mode_ss and the
// IMM's mode-matched filters).
//
// Covariance prediction:  P <- A P A' + Q   (Q read symmetrised; P comes out exactly symmetric).
// Measurement update with any subset of rows, in square-root innovation form:
//   S = Cs P Cs' + Rs = L L'   (Cholesky),   w = L^-1 (y - Cs x),   U = L^-1 Cs P,
//   x <- x + U' w   (= x + K (y - Cs x), K = P Cs' S^-1),
//   P <- P - U' U   (= P - K S K'; lower triangle computed, mirrored: exactly symmetric),
//   log N(y; Cs x, S) = -|w|^2 / 2 - sum log L_ii - m/2 log 2 pi.
// The update is split in factor() and apply() so that a caller can decide between the two
// (the IMM applies its modes' corrections only when every mode factored). When S is not
// positive definite (R singular, or P0 = 0 with R = 0) factor() says so; filters that
// want the minimum-variance gain anyway call apply_pseudo_inverse() (K = P Cs' S^+, the only
// path that allocates, and only on that failure).
//
// All storage is the caller's Workspace, sized once for the state size and the most rows an
// update can have: prediction and update never allocate. Sizes up to 8 run on code compiled for
// that size (fully unrolled); larger ones on the same loops with run-time bounds, and beyond 16
// states on Eigen's blocked products. Every path computes each coefficient in the same order
// (sums over the inner index in increasing order), so the fixed-size paths give the same bits
// as the run-time ones up to 16 states.
#pragma once

#include <Eigen/Dense>
#include <cstdint>

namespace ncosim::est::kalman {

struct Workspace {
  Workspace() = default;
  // n: state size; m_max: the most measurement rows of one update.
  Workspace(Eigen::Index n, Eigen::Index m_max) { reserve(n, m_max); }
  void reserve(Eigen::Index n, Eigen::Index m_max);

  // Filled by the caller for an update with m rows (or by select()): rows 0..m-1.
  Eigen::MatrixXd C;  // m_max x n: the selected rows of the output matrix
  Eigen::MatrixXd R;  // m_max x m_max: their noise covariance (only the lower triangle is read)
  Eigen::VectorXd y;  // m_max: their measured values
  Eigen::Index m = 0;

  // Results of factor(): L (lower triangle of `L`), w = L^-1 (y - C x), U = L^-1 C P.
  Eigen::MatrixXd L, U;
  Eigen::VectorXd w;

  Eigen::MatrixXd T;   // n x n scratch of the prediction
  Eigen::VectorXd xt;  // n scratch

  // log N(y; C x, S) of the last successful factor() (reads L's diagonal and w).
  double log_likelihood() const;
};

// P <- A P A' + Q.
void predict_covariance(const Eigen::MatrixXd& A, const Eigen::MatrixXd& Q, Eigen::MatrixXd& P,
                        Workspace& ws);
// x <- A x (the caller adds its input terms).
void predict_state(const Eigen::MatrixXd& A, Eigen::VectorXd& x, Workspace& ws);

// Fills ws.C, ws.R, ws.y with the rows rows[0..m-1] of (C, R, y); returns m.
Eigen::Index select(const Eigen::MatrixXd& C, const Eigen::MatrixXd& R, const Eigen::VectorXd& y,
                    const Eigen::Index* rows, Eigen::Index m, Workspace& ws);

enum class Factor {
  kOk,
  kNotPositiveDefinite,  // S is not positive definite (semidefinite, or lost to rounding)
  kNonFinite,            // the innovation or S is not finite
};
// Factors the update of (x, P) with ws.m rows (x and P are only read). Unless kOk, ws.L, ws.w
// and ws.U are unspecified.
Factor factor(const Eigen::VectorXd& x, const Eigen::MatrixXd& P, Workspace& ws);
// Applies a successful factor() to (x, P).
void apply(Eigen::VectorXd& x, Eigen::MatrixXd& P, const Workspace& ws);
// The minimum-variance update with a semidefinite S: K = P C' S^+ (allocates).
void apply_pseudo_inverse(Eigen::VectorXd& x, Eigen::MatrixXd& P, const Workspace& ws);
// The minimum-variance measurement update of (x, P) with ws.m rows: apply() when S is positive
// definite, the pseudo-inverse gain when it is only semidefinite (R singular, or P = 0 with
// R = 0: rows without information get no weight). Returns false, leaving (x, P) untouched, when
// the innovation or S is not finite.
//
// With `counted`, a positive definite S also adds its normalised innovation |w|^2 = nu' S^-1 nu
// (chi-square with m degrees of freedom for a consistent filter) to *counted; the pseudo-inverse
// path has no such S and adds nothing.
struct Innovations {
  double nis = 0.0;          // sum over the counted updates of nu' S^-1 nu
  std::int64_t dof = 0;      // sum of their rows (the chi-square degrees of freedom)
  std::int64_t updates = 0;  // updates counted
};
bool update(Eigen::VectorXd& x, Eigen::MatrixXd& P, Workspace& ws, Innovations* counted = nullptr);

}  // namespace ncosim::est::kalman
