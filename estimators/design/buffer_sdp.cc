// estimators/design/buffer_sdp.cc — the critical probability by the SDP of Schenato (2008),
// eq. (37), on the LMI layer (see buffer_design.h).
#include <Eigen/Eigenvalues>
#include <chrono>
#include <cmath>
#include <limits>

#include "estimators/design/buffer_design.h"
#include "lmi/lmi.h"

namespace ncosim::est::buffer {

namespace {

// Maximises the margin t of Psi_lambda(Y, Z) >= t I over 0 <= Y <= I, then checks the SDP's
// certificate exactly: by the Schur complement, Psi > 0 iff P = Y^-1 satisfies
// P > lambda G P G' + (1-lambda) A P A' with G = A + Y^-1 Z C, i.e. the spectral radius of
// lambda G⊗G + (1-lambda) A⊗A is below 1. Deciding by that radius rather than by t > threshold
// matters near lambda_c, where the certificates are ill-conditioned and t is below any fixed
// threshold (a margin of 1e-9 biased lambda_c up by up to 2e-3 on random systems).
// 1: feasible, 0: not certified, -1: the solver failed (other than infeasible).
int psi_feasible(const Eigen::MatrixXd& A, const Eigen::MatrixXd& C, double lambda) {
  const int n = static_cast<int>(A.rows()), m = static_cast<int>(C.rows());
  lmi::Problem prob;
  const lmi::Var Y = prob.symmetric(n, "Y");
  const lmi::Var Z = prob.full(n, m, "Z");
  const lmi::Var t = prob.symmetric(1, "t");
  const double a = std::sqrt(lambda), b = std::sqrt(1.0 - lambda);
  const Eigen::MatrixXd O = Eigen::MatrixXd::Zero(n, n);
  const lmi::Expr YA = lmi::Expr(Y) * A;
  const lmi::Expr top = a * (YA + lmi::Expr(Z) * C);
  const lmi::Expr psi =
      lmi::block({{Y, top, b * YA}, {top.transpose(), Y, O}, {b * YA.transpose(), O, Y}});
  const int d = 3 * n;
  lmi::Expr tI = Eigen::MatrixXd::Zero(d, d);
  for (int i = 0; i < d; ++i) {
    const Eigen::MatrixXd e = Eigen::VectorXd::Unit(d, i);
    tI += e * t * e.transpose();
  }
  prob.add(psi - tI >= 0);
  prob.add(lmi::Expr(Y) >= 0);
  prob.add(Eigen::MatrixXd::Identity(n, n) - lmi::Expr(Y) >= 0);
  prob.add(lmi::Expr(t) <= Eigen::MatrixXd::Ones(1, 1));
  prob.maximize(lmi::entry(t, 0, 0));
  const lmi::Solution s = prob.solve();
  if (s.status == lmi::Status::kInfeasible) return 0;
  if (!s.ok()) return -1;
  const Eigen::MatrixXd Yv = s.value(Y), Zv = s.value(Z);
  Eigen::LLT<Eigen::MatrixXd> llt(Yv);
  if (llt.info() != Eigen::Success) return 0;
  // Psi > 0  <=>  Y > lambda G' Y G + (1-lambda) A' Y A with G = A + Y^-1 Z C (Schur complement).
  const Eigen::MatrixXd G = A + llt.solve(Zv) * C;
  Eigen::MatrixXd T(n * n, n * n);
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      T.block(i * n, j * n, n, n) = lambda * G(i, j) * G + (1.0 - lambda) * A(i, j) * A;
    }
  }
  Eigen::EigenSolver<Eigen::MatrixXd> es(T, false);
  return es.info() == Eigen::Success && es.eigenvalues().cwiseAbs().maxCoeff() < 1.0 ? 1 : 0;
}

}  // namespace

CriticalProbability critical_probability_sdp(const Plant& plant, double tolerance) {
  const auto t0 = std::chrono::steady_clock::now();
  Plant p;
  CriticalProbability cp = critical_probability_start(plant, p);
  bool failed = false;
  auto feasible = [&](double lambda) {
    ++cp.evaluations;
    const int f = psi_feasible(p.A, p.C[0], lambda);
    if (f < 0) failed = true;
    return f == 1;
  };
  if (cp.spectral_radius < 1.0) {
    cp.value = 0.0;
  } else if (!feasible(1.0)) {
    cp.value = 1.0;
    cp.detectable = false;
  } else {
    double lo = cp.lower_bound, hi = 1.0;
    while (hi - lo > tolerance && !failed) {
      const double mid = 0.5 * (lo + hi);
      (feasible(mid) ? hi : lo) = mid;
    }
    cp.value = hi;
  }
  if (failed) cp.value = std::numeric_limits<double>::quiet_NaN();
  cp.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return cp;
}

}  // namespace ncosim::est::buffer
