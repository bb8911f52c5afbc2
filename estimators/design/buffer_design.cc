// estimators/design/buffer_design.cc — see buffer_design.h.
#include "estimators/design/buffer_design.h"

#include <fmt/format.h>

#include <Eigen/Eigenvalues>
#include <Eigen/QR>
#include <chrono>
#include <cmath>
#include <limits>

namespace ncosim::est::buffer {

namespace {

Eigen::MatrixXd kron(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  Eigen::MatrixXd out(a.rows() * b.rows(), a.cols() * b.cols());
  for (Eigen::Index i = 0; i < a.rows(); ++i) {
    for (Eigen::Index j = 0; j < a.cols(); ++j)
      out.block(i * b.rows(), j * b.cols(), b.rows(), b.cols()) = a(i, j) * b;
  }
  return out;
}

double spectral_radius(const Eigen::MatrixXd& m) {
  if (!m.allFinite()) return std::numeric_limits<double>::infinity();
  Eigen::EigenSolver<Eigen::MatrixXd> es(m, /*computeEigenvectors=*/false);
  if (es.info() != Eigen::Success) return std::numeric_limits<double>::infinity();
  return es.eigenvalues().cwiseAbs().maxCoeff();
}

Eigen::MatrixXd sym(const Eigen::MatrixXd& m) { return 0.5 * (m + m.transpose()); }

// k-th Kronecker power.
Eigen::MatrixXd kron_power(const Eigen::MatrixXd& a, int k) {
  Eigen::MatrixXd out = a;
  for (int i = 1; i < k; ++i) out = kron(out, a);
  return out;
}

// E[F^{⊗k}] for F = A prod_i (I - gamma_i K_i C_i), sensor 0 applied first: by independence and
// the mixed-product rule, A^{⊗k} M_{S-1} ... M_0 with M_i = lambda_i G_i^{⊗k} + (1-lambda_i) I.
Eigen::MatrixXd moment_operator(const Plant& p, const std::vector<double>& lambda, const Gains& K,
                                int k) {
  const Eigen::Index n = p.A.rows();
  const Eigen::MatrixXd I = Eigen::MatrixXd::Identity(n, n);
  Eigen::MatrixXd out = kron_power(p.A, k);
  for (int i = p.sensors() - 1; i >= 0; --i) {
    const auto ui = static_cast<std::size_t>(i);
    const Eigen::MatrixXd Gk = kron_power(I - K[ui] * p.C[ui], k);
    const Eigen::MatrixXd M =
        lambda[ui] * Gk + (1.0 - lambda[ui]) * Eigen::MatrixXd::Identity(Gk.rows(), Gk.cols());
    out = (out * M).eval();
  }
  return out;
}

}  // namespace

Eigen::MatrixXd gain(const Eigen::MatrixXd& C, const Eigen::MatrixXd& R, const Eigen::MatrixXd& P) {
  const Eigen::MatrixXd PCt = P * C.transpose();
  const Eigen::MatrixXd S = C * PCt + R;
  Eigen::LLT<Eigen::MatrixXd> llt(S);
  if (llt.info() == Eigen::Success) return llt.solve(PCt.transpose()).transpose();
  return PCt * S.completeOrthogonalDecomposition().pseudoInverse();
}

Gains slot_gains(const Plant& p, const std::vector<double>& lambda, const Eigen::MatrixXd& P) {
  Gains K;
  Eigen::MatrixXd Pi = P;
  for (int i = 0; i < p.sensors(); ++i) {
    const auto ui = static_cast<std::size_t>(i);
    K.push_back(gain(p.C[ui], p.R[ui], Pi));
    Pi = sym(Pi - lambda[ui] * K.back() * p.C[ui] * Pi);
  }
  return K;
}

Eigen::MatrixXd filtered(const Plant& p, const std::vector<double>& lambda, const Gains& K,
                         const Eigen::MatrixXd& P) {
  const Eigen::Index n = p.A.rows();
  Eigen::MatrixXd Pi = P;
  for (int i = 0; i < p.sensors(); ++i) {
    const auto ui = static_cast<std::size_t>(i);
    const Eigen::MatrixXd IKC = Eigen::MatrixXd::Identity(n, n) - K[ui] * p.C[ui];
    Pi = sym(lambda[ui] * (IKC * Pi * IKC.transpose() + K[ui] * p.R[ui] * K[ui].transpose()) +
             (1.0 - lambda[ui]) * Pi);
  }
  return Pi;
}

Eigen::MatrixXd l_op(const Plant& p, const std::vector<double>& lambda, const Gains& K,
                     const Eigen::MatrixXd& P) {
  return sym(p.A * filtered(p, lambda, K, P) * p.A.transpose() + p.Q);
}

Eigen::MatrixXd phi(const Plant& p, const std::vector<double>& lambda, const Eigen::MatrixXd& P) {
  Eigen::MatrixXd Pi = P;
  for (int i = 0; i < p.sensors(); ++i) {
    const auto ui = static_cast<std::size_t>(i);
    const Eigen::MatrixXd K = gain(p.C[ui], p.R[ui], Pi);
    Pi = sym(Pi - lambda[ui] * K * p.C[ui] * Pi);
  }
  return sym(p.A * Pi * p.A.transpose() + p.Q);
}

double second_moment_radius(const Plant& p, const std::vector<double>& lambda, const Gains& K) {
  return spectral_radius(moment_operator(p, lambda, K, 2));
}

double fourth_moment_radius(const Plant& p, const std::vector<double>& lambda, const Gains& K) {
  if (p.A.rows() > 7) return std::numeric_limits<double>::quiet_NaN();
  return spectral_radius(moment_operator(p, lambda, K, 4));
}

std::optional<Eigen::MatrixXd> l_fixed_point(const Plant& p, const std::vector<double>& lambda,
                                             const Gains& K) {
  const Eigen::Index n = p.A.rows();
  const Eigen::MatrixXd T = moment_operator(p, lambda, K, 2);
  if (!(spectral_radius(T) < 1.0)) return std::nullopt;
  // L is affine: L(P) = T vec(P) + L(0).
  const Eigen::MatrixXd c = l_op(p, lambda, K, Eigen::MatrixXd::Zero(n, n));
  const Eigen::VectorXd rhs = Eigen::Map<const Eigen::VectorXd>(c.data(), n * n);
  const Eigen::VectorXd v = (Eigen::MatrixXd::Identity(n * n, n * n) - T).partialPivLu().solve(rhs);
  Eigen::MatrixXd P = sym(Eigen::Map<const Eigen::MatrixXd>(v.data(), n, n));
  if (!P.allFinite()) return std::nullopt;
  return P;
}

RiccatiFixedPoint riccati_fixed_point(const Plant& p, const std::vector<double>& lambda,
                                      int max_value_iterations) {
  const Eigen::Index n = p.A.rows();
  RiccatiFixedPoint out;
  Eigen::MatrixXd P = Eigen::MatrixXd::Zero(n, n);
  const double blowup = 1e14 * std::max(1.0, p.Q.trace());
  for (int it = 0; it < max_value_iterations; ++it) {
    P = phi(p, lambda, P);
    ++out.iterations;
    if (!P.allFinite() || P.trace() > blowup) break;
    if (it % 4 != 0) continue;
    auto T = l_fixed_point(p, lambda, slot_gains(p, lambda, P));
    if (!T) continue;
    // Policy iteration: each gain is stabilising when the previous one was (Q > 0), and the
    // covariances decrease monotonically to the fixed point.
    for (int j = 0; j < 100; ++j) {
      ++out.iterations;
      auto next = l_fixed_point(p, lambda, slot_gains(p, lambda, *T));
      if (!next) break;  // only by rounding at the edge of stability: keep the last one
      const double change = (*next - *T).norm();
      T = std::move(next);
      if (change <= 1e-14 * T->norm()) break;
    }
    out.exists = true;
    out.P = *T;
    return out;
  }
  out.P = P;
  return out;
}

Plant stacked(const Plant& p) {
  Plant s;
  s.A = p.A;
  s.Q = p.Q;
  Eigen::Index rows = 0;
  for (const auto& c : p.C) rows += c.rows();
  Eigen::MatrixXd C(rows, p.A.cols()), R = Eigen::MatrixXd::Zero(rows, rows);
  Eigen::Index r = 0;
  for (std::size_t i = 0; i < p.C.size(); ++i) {
    C.middleRows(r, p.C[i].rows()) = p.C[i];
    R.block(r, r, p.C[i].rows(), p.C[i].rows()) = p.R[i];
    r += p.C[i].rows();
  }
  s.C = {C};
  s.R = {R};
  return s;
}

Plant compressed(const Plant& plant) {
  const Eigen::Index n = plant.A.cols();
  Eigen::Index rows = 0;
  for (const auto& c : plant.C) rows += c.rows();
  if (rows <= n) return stacked(plant);
  // Whitened rows L_i^-1 C_i (R_i = L_i L_i'), one sensor at a time: O(rows n^2) in all.
  Eigen::MatrixXd W(rows, n);
  Eigen::Index r = 0;
  for (std::size_t i = 0; i < plant.C.size(); ++i) {
    const Eigen::LLT<Eigen::MatrixXd> llt(plant.R[i]);
    if (llt.info() != Eigen::Success) return stacked(plant);  // R_i singular: no whitening
    const Eigen::MatrixXd L = llt.matrixL();
    if (!(L.diagonal().minCoeff() > 1e-12 * L.diagonal().maxCoeff())) return stacked(plant);
    W.middleRows(r, plant.C[i].rows()) = llt.matrixL().solve(plant.C[i]);
    r += plant.C[i].rows();
  }
  if (!W.allFinite()) return stacked(plant);
  // W = Q T (thin QR): C' R^-1 C = W' W = T' T, so (T, I) gives the same Phi and the same row
  // space.
  const Eigen::HouseholderQR<Eigen::MatrixXd> qr(W);
  Plant s;
  s.A = plant.A;
  s.Q = plant.Q;
  const Eigen::MatrixXd T = qr.matrixQR().topRows(n).triangularView<Eigen::Upper>();
  s.C = {T};
  s.R = {Eigen::MatrixXd::Identity(n, n)};
  return s;
}

CriticalProbability critical_probability_start(const Plant& plant, Plant& p) {
  p = plant.sensors() == 1 ? plant : compressed(plant);
  CriticalProbability cp;
  const Eigen::VectorXcd eig = p.A.eigenvalues();
  double rho = 0.0, prod = 1.0;
  for (Eigen::Index i = 0; i < eig.size(); ++i) {
    const double a = std::abs(eig(i));
    rho = std::max(rho, a);
    if (a >= 1.0) prod *= a * a;
  }
  cp.lower_bound = rho < 1.0 ? 0.0 : 1.0 - 1.0 / (rho * rho);
  cp.upper_bound = 1.0 - 1.0 / prod;
  cp.spectral_radius = rho;
  return cp;
}

CriticalProbability critical_probability_bisection(const Plant& plant, double tolerance) {
  const auto t0 = std::chrono::steady_clock::now();
  Plant p;
  CriticalProbability cp = critical_probability_start(plant, p);
  auto exists = [&](double lambda) {
    ++cp.evaluations;
    return riccati_fixed_point(p, {lambda}, 20000).exists;
  };
  if (cp.spectral_radius < 1.0) {
    cp.value = 0.0;  // Phi_0 (open loop) already has a fixed point
  } else if (!exists(1.0)) {
    cp.value = 1.0;
    cp.detectable = false;
  } else {
    double lo = cp.lower_bound, hi = 1.0;
    while (hi - lo > tolerance) {
      const double mid = 0.5 * (lo + hi);
      (exists(mid) ? hi : lo) = mid;
    }
    cp.value = hi;
  }
  cp.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return cp;
}

namespace {
std::vector<double> column(const std::vector<std::vector<double>>& lambda, std::size_t k) {
  std::vector<double> out;
  for (const auto& l : lambda) out.push_back(l[k]);
  return out;
}
}  // namespace

std::vector<Eigen::MatrixXd> covariances_of_gains(const Plant& p,
                                                  const std::vector<std::vector<double>>& lambda,
                                                  const std::vector<Gains>& K) {
  const std::size_t N = lambda.front().size();
  std::vector<Eigen::MatrixXd> T(N + 1);
  auto last = l_fixed_point(p, column(lambda, N - 1), K[N - 1]);
  if (!last) return {};
  T[N] = *last;
  for (std::size_t k = N; k-- > 0;) T[k] = l_op(p, column(lambda, k), K[k], T[k + 1]);
  return T;
}

StaticGains design_static_gains(const Plant& p, const std::vector<std::vector<double>>& lambda) {
  StaticGains g;
  const std::size_t N = lambda.front().size();
  g.N = static_cast<int>(N);
  const auto fp = riccati_fixed_point(p, column(lambda, N - 1));
  g.stable = fp.exists;
  g.V.assign(N + 1, Eigen::MatrixXd());
  g.K.assign(N, Gains());
  g.V[N] = fp.P;
  for (std::size_t k = N; k-- > 0;) {
    const auto lk = column(lambda, k);
    g.K[k] = slot_gains(p, lk, g.V[k + 1]);
    g.V[k] = phi(p, lk, g.V[k + 1]);
  }
  g.second_moment_radius = second_moment_radius(p, column(lambda, N - 1), g.K[N - 1]);
  g.fourth_moment_radius = fourth_moment_radius(p, column(lambda, N - 1), g.K[N - 1]);
  if (!g.stable) {
    std::string l;
    for (const auto& li : lambda) l += fmt::format("{}{:.6g}", l.empty() ? "" : ", ", li[N - 1]);
    g.status = fmt::format(
        "unstable: no fixed point of Phi at lambda_{} = {} (lambda_c not exceeded)", N - 1, l);
    g.trace_V0 = std::numeric_limits<double>::infinity();
    g.filtered =
        Eigen::MatrixXd::Constant(p.A.rows(), p.A.rows(), std::numeric_limits<double>::infinity());
    return g;
  }
  g.filtered = filtered(p, column(lambda, 0), g.K[0], g.V[1]);
  g.trace_V0 = g.V[0].trace();
  return g;
}

}  // namespace ncosim::est::buffer
