// estimators/extended_model.h — the delay-extended model of Dolz et al. (2014), eqs. (3)–(5), (9).
// xbar[t] = [x[t]; x[t-1]; ...; x[t-dbar]] (size n (dbar+1)); "sensor i with delay d" is the
// fictitious sensor j = i (dbar+1) + d (0-based) with rows cbar_j = [0 .. C_i .. 0] (C_i in
// block d). A sensor with several outputs is one fictitious sensor per delay (its rows travel
// in one packet). Pattern probabilities follow the design model: packets sent at different
// periods are independent, and a packet of a buffered sensor delivers every fictitious sensor
// it carries together.
#pragma once

#include <Eigen/Dense>
#include <cstdint>
#include <vector>

#include "estimators/estimator.h"

namespace ncosim::est {

struct ExtendedModel {
  int dbar = 0;
  Eigen::Index n = 0;    // plant state size
  Eigen::Index nb = 0;   // n (dbar + 1)
  Eigen::Index nmb = 0;  // total fictitious output rows: (sum of ny) (dbar + 1)
  Eigen::Index nu = 0;
  Eigen::Index nw = 0;
  Eigen::MatrixXd A;  // Abar (nb x nb)
  Eigen::MatrixXd Q;  // Bbar_w W Bbar_w' (nb x nb)
  Eigen::MatrixXd C;  // Cbar (nmb x nb)
  Eigen::MatrixXd V;  // block-diagonal noise covariance of the fictitious rows (nmb x nmb)
  struct Fictitious {
    int sensor;
    int delay;
    Eigen::Index row;   // first row in Cbar
    Eigen::Index rows;  // ny of the sensor
  };
  std::vector<Fictitious> fict;  // index j = sensor (dbar+1) + delay
  int sensors = 0;

  int fictitious_count() const { return static_cast<int>(fict.size()); }
  int index(int sensor, int delay) const { return sensor * (dbar + 1) + delay; }
  // 0/1 row-selection vector of a pattern (bit j = fictitious sensor j delivered).
  Eigen::VectorXd row_mask(std::uint64_t pattern) const;
  // Number of distinct real sensors in a pattern.
  int real_sensors(std::uint64_t pattern) const;
};

ExtendedModel build_extended(const Model& model, int dbar);

// P[alpha = pattern] for every pattern 0 .. 2^nf - 1 under the design model.
// Requires nf <= 24 (the caller reports a clear error beyond).
std::vector<double> pattern_probabilities(const Model& model, const ExtendedModel& ext);

// Expected covariance at every period from the covariance P at update instants, with
// p0 = P[no measurement] (Dolz eq. (28) corrected: results/README.md, Dolz Fig. 3):
// Pt = (1-p0) P + p0 [(1-p0) Abar S_P Abar' + S'_W],  S_X = sum_k p0^k Abar^k X Abar^k'.
// `stein` is (I - p0 Abar ⊗ Abar)^{-1}.
Eigen::MatrixXd stein_sum(const Eigen::MatrixXd& stein, const Eigen::MatrixXd& X);
Eigen::MatrixXd stein_operator(const Eigen::MatrixXd& A, double p0);

}  // namespace ncosim::est
