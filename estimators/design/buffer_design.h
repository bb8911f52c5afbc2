// estimators/design/buffer_design.h — Schenato (2008): the operators of the buffered
// estimators, the optimal static gains of Theorem 3, and the critical arrival probability.
// Notation (scenarios/README.md, static_buffer):
//   L_lambda(K, P) = lambda A(I-KC)P(I-KC)'A' + (1-lambda) A P A' + Q + lambda A K R K' A'
//   Phi_lambda(P)  = A P A' + Q - lambda A P C'(C P C' + R)^-1 C P A'   (= min_K L_lambda(K, P))
// lambda_h = P[delay <= h]. Every covariance here is of a one-step prediction error unless
// it says "filtered".
#pragma once

#include <Eigen/Dense>
#include <optional>
#include <string>
#include <vector>

namespace ncosim::est::buffer {

// Several sensors are corrected one after the other inside a slot (sensor 0 first), each with
// its own arrival probability and gain; arrivals of different packets are independent. With one
// sensor every formula is the paper's. `lambda` below always has one entry per sensor.
struct Plant {
  Eigen::MatrixXd A, Q;            // Q = Bw W Bw'
  std::vector<Eigen::MatrixXd> C;  // per sensor
  std::vector<Eigen::MatrixXd> R;  // per sensor noise covariance
  int sensors() const { return static_cast<int>(C.size()); }
};
using Gains = std::vector<Eigen::MatrixXd>;  // one per sensor

// K = P C'(C P C' + R)^-1 (pseudo-inverse when C P C' + R is singular).
Eigen::MatrixXd gain(const Eigen::MatrixXd& C, const Eigen::MatrixXd& R, const Eigen::MatrixXd& P);
// The optimal gains of a slot with prior covariance P: sensor i's gain from the expected
// covariance after the corrections of sensors 0..i-1.
Gains slot_gains(const Plant& p, const std::vector<double>& lambda, const Eigen::MatrixXd& P);
Eigen::MatrixXd phi(const Plant& p, const std::vector<double>& lambda, const Eigen::MatrixXd& P);
Eigen::MatrixXd l_op(const Plant& p, const std::vector<double>& lambda, const Gains& K,
                     const Eigen::MatrixXd& P);
// Filtered covariance of a slot whose prior covariance is P, sensor i corrected with K_i with
// probability lambda_i: per sensor lambda [(I-KC)P(I-KC)' + K R K'] + (1-lambda) P.
Eigen::MatrixXd filtered(const Plant& p, const std::vector<double>& lambda, const Gains& K,
                         const Eigen::MatrixXd& P);

// Spectral radius of the second-moment operator of e+ = A prod_i (I - gamma_i K_i C_i) e
// (gamma_i ~ Bernoulli(lambda_i), independent): rho(E[F⊗F]).
double second_moment_radius(const Plant& p, const std::vector<double>& lambda, const Gains& K);
// The same for the fourth moment, rho(E[F⊗F⊗F⊗F]): below 1 iff E|e|^4 stays bounded (|e|^2
// has a finite variance). NaN for n > 7 (the n^4 x n^4 operator would be too large).
double fourth_moment_radius(const Plant& p, const std::vector<double>& lambda, const Gains& K);
// The fixed point T = L_lambda(K, T) (a linear equation), or nullopt when the
// second-moment radius is >= 1 (no bounded stationary covariance).
std::optional<Eigen::MatrixXd> l_fixed_point(const Plant& p, const std::vector<double>& lambda,
                                             const Gains& K);

// The fixed point of Phi_lambda (the modified algebraic Riccati equation). Value iteration
// from 0 until the gains of an iterate make L_lambda(K, .) stable (a certificate that the
// fixed point exists: it bounds the monotone iterates), then policy iteration (quadratic
// convergence). `exists` is false when the iterates blow up or no certificate is found within
// the iteration budget.
struct RiccatiFixedPoint {
  bool exists = false;
  Eigen::MatrixXd P;   // the fixed point when it exists, else the last iterate
  int iterations = 0;  // value + policy iterations
};
RiccatiFixedPoint riccati_fixed_point(const Plant& p, const std::vector<double>& lambda,
                                      int max_value_iterations = 200000);

// lambda_c = inf { lambda : Phi_lambda has a fixed point } for every sensor arriving together
// (the sensors' rows stacked into one C), by bisection on the existence of the fixed point in
// [1 - 1/rho(A)^2, 1]. A stable A gives 0. When the fixed point does not exist even at
// lambda = 1 (an undetectable pair), value 1 and detectable = false.
struct CriticalProbability {
  double value = 0.0;
  double lower_bound = 0.0;      // 1 - 1/rho(A)^2 (0 for a stable A), always a lower bound
  double upper_bound = 0.0;      // 1 - 1/prod |unstable eigenvalues|^2 (exact when C is invertible
                                 // or for one unstable mode; not a bound in general)
  double spectral_radius = 0.0;  // rho(A)
  bool detectable = true;
  int evaluations = 0;  // fixed-point existence checks
  double seconds = 0.0;
};
CriticalProbability critical_probability_bisection(const Plant& p, double tolerance = 1e-7);

// Theorem 3 with the gain indexing of scenarios/README.md, for lambda[i][k] = P[delay of sensor i
// <= k], k = 0 .. N-1: V_N = fixed point of Phi_{lambda_{N-1}}, V_k = Phi_{lambda_k}(V_{k+1}),
// K_k = slot_gains(V_{k+1}) (K_k = V_{k+1} C'(C V_{k+1} C' + R)^-1 for one sensor). The slot of
// delay k (0 = the newest) is corrected with K_k.
struct StaticGains {
  int N = 0;
  std::vector<Gains> K;               // K[k][i]: delay k, sensor i
  std::vector<Eigen::MatrixXd> V;     // V_0 .. V_N (V_N the last value iterate when unstable)
  bool stable = false;                // the fixed point exists (lambda_{N-1} > lambda_c)
  Eigen::MatrixXd filtered;           // stationary covariance of x[t] - xhat[t|t]
  double trace_V0 = 0.0;              // the paper's Fig. 6 quantity
  double second_moment_radius = 0.0;  // of the oldest slot's recursion (< 1 when stable)
  double fourth_moment_radius = 0.0;  // >= 1: |e|^2 has an infinite variance
  std::string status = "ok";          // "ok" or "unstable: ..."
};
// lambda[i] = lambda_0 .. lambda_{N-1} of sensor i (all of the same length N >= 1).
StaticGains design_static_gains(const Plant& p, const std::vector<std::vector<double>>& lambda);

// The covariances T_N = fixed point of L_{lambda_{N-1}}(K_{N-1}, .), T_k = L_{lambda_k}(K_k,
// T_{k+1}) of any gains; T_0 is the one-step prediction covariance. Empty when the oldest
// slot's recursion is not mean-square stable.
std::vector<Eigen::MatrixXd> covariances_of_gains(const Plant& p,
                                                  const std::vector<std::vector<double>>& lambda,
                                                  const std::vector<Gains>& K);

// The same by the SDP of Schenato's eq. (37) (Sinopoli et al. 2004, Theorem 5): the fixed point
// exists iff there are Y, Z with 0 <= Y <= I and
//   Psi_lambda(Y, Z) = [[Y, sqrt(l)(Y A + Z C), sqrt(1-l) Y A], [*, Y, 0], [*, 0, Y]] > 0,
// decided on CSDP (lmi/lmi.h) as the feasibility of Y >= I, Psi >= I (Psi is homogeneous in (Y,
// Z)). Bisection on lambda in [lower bound, 1] as above. `evaluations` counts the SDPs solved; a
// solver failure (other than infeasible) makes value NaN.
CriticalProbability critical_probability_sdp(const Plant& p, double tolerance = 1e-7);

// The sensors' rows stacked into one sensor (for the critical probability).
Plant stacked(const Plant& p);

// The sensors' rows stacked and, when they outnumber the states and every R_i is positive
// definite, compressed to n rows with the same information: C_eq = T from the thin QR of the
// whitened rows [L_1^-1 C_1; ...] = Q T (R_i = L_i L_i'), R_eq = I. C_eq' C_eq = C' R^-1 C, so
// Phi_lambda is the same map (and the row space, all the SDP sees, the same): lambda_c is
// unchanged, at a cost independent of the number of sensors (1001 stacked rows took minutes).
Plant compressed(const Plant& p);

// The start of both lambda_c computations: p with its sensors stacked (compressed), and a result
// holding the eigenvalue bounds (lower_bound, upper_bound) of A.
CriticalProbability critical_probability_start(const Plant& plant, Plant& stacked_plant);

}  // namespace ncosim::est::buffer
