// estimators/design/jump_design.h — offline design of the jump observer gains L(N, pattern)
// (Dolz et al. 2014, eqs. (16)–(23)), method "iterative".
// Each term of the expected-covariance operator (18) is w (F X F' + L eta V eta L') with
// F = I - L eta Cbar. S4 (a gain per (N, pattern)) uses the closed-form minimiser
// L = X Cs'(Cs X Cs' + Vs)^-1 and iterates P <- min_L E_L{P} from P = 0 (exact value
// iteration). S1–S3 share a gain across a group of (N, pattern) terms and use the
// trace-minimising shared gain L = (sum w X Cbar' eta)(sum w eta (Cbar X Cbar' + V) eta)^+.
// Failure (p0 rho(Abar)^2 >= 1, divergence, no convergence) is a status, never a throw.
#pragma once

#include <Eigen/Dense>
#include <cstdint>
#include <string>
#include <vector>

#include "estimators/extended_model.h"

namespace ncosim::est {

enum class Grouping { kS1, kS2, kS3, kS4 };

struct JumpDesign {
  Grouping grouping = Grouping::kS4;
  int Nbar = 1;
  std::vector<Eigen::MatrixXd> gains;     // one per group (nb x nmb)
  std::vector<std::vector<int>> gain_of;  // [N-1][pattern] -> index into gains, -1 for 0
  std::vector<Eigen::VectorXd> masks;     // [pattern] -> 0/1 row mask (alpha of eq. 10)
  long stored_gains = 0;                  // the paper's count |L|
  double p0 = 0.0;                        // P[no measurement in a period]
  Eigen::MatrixXd P;                      // covariance at update instants
  Eigen::MatrixXd Pt;                     // covariance at every period (corrected eq. 28)
  // Eq. (28) exactly as printed, which weights the N >= 1 terms by p0^N instead of (1-p0) p0^N:
  // (1-p0) P + p0 sum_k p0^k Abar^k (Abar P Abar' + Bw W Bw' / (1-p0)) Abar^k'. Wrong (simulation
  // follows Pt); kept only to reproduce the paper's Fig. 3 and Fig. 1(a) text (results/README.md).
  Eigen::MatrixXd Pt_paper_eq28_erroneous;
  int iterations = 0;
  // Set when not_converged because the change stopped decreasing before max_iterations (a floor
  // of rounding noise far above the tolerance): where, at what change, and what to do.
  std::string iteration_message;
  bool stable = false;
  std::string status = "ok";
};

// Group of the term (N, pattern) and the number of groups per N.
int group_of(Grouping g, const ExtendedModel& ext, std::uint64_t pattern);
int groups_per_N(Grouping g, const ExtendedModel& ext);

// The history terms of (18) shared by every design method: Apow[N] = Abar^N and
// SW[N] = sum_{j<N} Abar^j Q Abar^j' for N = 0..Nbar, the Stein operator of p0, S'_W,inf
// (eq. 23) and the tail's noise SW[Nbar] + p0 Abar^Nbar S'_W,inf Abar^Nbar'.
struct HistoryTerms {
  std::vector<Eigen::MatrixXd> Apow, SW;
  Eigen::MatrixXd stein, SWinf, tail_noise;
};
HistoryTerms history_terms(const ExtendedModel& ext, double p0, int Nbar);

// Weight of the terms of N in (18): p0^(N-1); the tail N = Nbar sums every N >= Nbar.
double history_weight(double p0, int N, int Nbar);

// Why no design can exist ("no_measurements" for p0 >= 1, "unstable: p0 rho(A)^2 = X >= 1"),
// or "" when one can.
std::string design_precheck(const ExtendedModel& ext, double p0);

JumpDesign design_jump_iterative(const ExtendedModel& ext, const std::vector<double>& pattern_prob,
                                 int Nbar, Grouping grouping, int max_iterations = 200000,
                                 double tolerance = 1e-13);

// Covariances of given gains (one per group, as JumpDesign::gains): P is the fixed point of
// the operator (18) with these gains, solved exactly as a linear equation in vec(P), and Pt
// the corrected eq. (28). Every design method reports its prediction through this function,
// so predicted values of different methods are computed the same way. Groups that no term of
// positive probability uses get the gain of design_jump_iterative's fallback formula at the
// fixed point. status "unstable_gains" when the operator's spectral radius is >= 1.
JumpDesign evaluate_jump_gains(const ExtendedModel& ext, const std::vector<double>& pattern_prob,
                               int Nbar, Grouping grouping,
                               const std::vector<Eigen::MatrixXd>& gains);

}  // namespace ncosim::est
