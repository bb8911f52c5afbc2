// estimators/design/sod_bounds.h — the send-on-delta paper's bounds relating a threshold
// Delta_i to the lower bound beta'_i of the send probability and to the virtual-noise variance
// sigma^2_delta_i in the least excited case (section 3.3.2), and the co-design costs of
// section 4. Pure functions (no LMI), shared by the sod_jump design and the co-design.
#pragma once

#include <Eigen/Dense>

namespace ncosim::est::sod {

// (28): r_i = sum_j (sum_k |C_ik B_kj|) ||w_j||_inf + 2 ||v_i||_inf.
Eigen::VectorXd uniform_range(const Eigen::MatrixXd& C, const Eigen::MatrixXd& Bw,
                              const Eigen::VectorXd& w_inf, const Eigen::VectorXd& v_inf);

// Uniform assumption, Lemma 1: (29) beta' = (r - Delta)^2 / r^2 and (30)
// sigma^2 = 2 Delta^3 / r^2 (r/3 - Delta/4) for Delta <= r; beta' = 0, sigma^2 = r^2/6 beyond.
double uniform_beta(double delta, double r);
double uniform_sigma2(double delta, double r);
// The threshold giving send probability `beta` (inverse of (29)), beta in [0, 1].
double uniform_delta_for_beta(double beta, double r);

// Gaussian assumption, Lemma 2: (33) beta' = 1 - erf(Delta / (sqrt 2 sigma)) and (34)
// sigma^2_delta = sigma^2 erf(.) - sqrt(2/pi) Delta sigma exp(-Delta^2 / (2 sigma^2)).
double gaussian_beta(double delta, double sigma);
double gaussian_sigma2(double delta, double sigma);
double gaussian_delta_for_beta(double beta, double sigma);

// Co-design costs: (35) J = sum g_i / Delta_i (deterministic) and (36) J = 1 - prod (1 - beta'_i).
double cost_deterministic(const Eigen::VectorXd& delta, const Eigen::VectorXd& g);
double cost_stochastic(const Eigen::VectorXd& beta);

}  // namespace ncosim::est::sod
