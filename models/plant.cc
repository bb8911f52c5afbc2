// models/plant.cc — lti and lti_continuous plant readers; exact discretisation.
#include "models/plant.h"

#include <fmt/format.h>

#include <unsupported/Eigen/MatrixFunctions>

namespace ncosim::models {

double LinearPlant::spectral_radius() const {
  if (A.size() == 0) return 0.0;
  return A.eigenvalues().cwiseAbs().maxCoeff();
}

Eigen::MatrixXd psd_sqrt(const Eigen::MatrixXd& M) {
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(0.5 * (M + M.transpose()));
  const Eigen::VectorXd d = es.eigenvalues().cwiseMax(0.0).cwiseSqrt();
  return es.eigenvectors() * d.asDiagonal() * es.eigenvectors().transpose();
}

LinearPlant discretise(const Eigen::MatrixXd& Ac, const Eigen::MatrixXd& Bc,
                       const Eigen::MatrixXd& Gc, const Eigen::MatrixXd& Wc, double period) {
  const Eigen::Index n = Ac.rows();
  const Eigen::Index nu = Bc.cols();
  LinearPlant p;
  // ZOH: expm([[Ac, Bc], [0, 0]] T) = [[A, Bu], [0, I]].
  Eigen::MatrixXd M = Eigen::MatrixXd::Zero(n + nu, n + nu);
  M.topLeftCorner(n, n) = Ac * period;
  if (nu > 0) M.topRightCorner(n, nu) = Bc * period;
  const Eigen::MatrixXd E = M.exp();
  p.A = E.topLeftCorner(n, n);
  p.Bu = E.topRightCorner(n, nu);
  // Van Loan: expm([[-Ac, Q], [0, Ac']] T) = [[., G12], [0, G22]], W = G22' G12.
  const Eigen::MatrixXd Qc = Gc * Wc * Gc.transpose();
  Eigen::MatrixXd V = Eigen::MatrixXd::Zero(2 * n, 2 * n);
  V.topLeftCorner(n, n) = -Ac * period;
  V.topRightCorner(n, n) = Qc * period;
  V.bottomRightCorner(n, n) = Ac.transpose() * period;
  const Eigen::MatrixXd G = V.exp();
  const Eigen::MatrixXd W = G.bottomRightCorner(n, n).transpose() * G.topRightCorner(n, n);
  p.W = 0.5 * (W + W.transpose());
  p.Bw = Eigen::MatrixXd::Identity(n, n);
  p.x0 = Eigen::VectorXd::Zero(n);
  return p;
}

namespace {

Eigen::MatrixXd read_square(const sim::Table& t, std::string_view key) {
  Eigen::MatrixXd A = t.matrix(key);
  if (A.rows() != A.cols()) {
    t.fail(key, fmt::format("expected a square matrix, got {}x{}", A.rows(), A.cols()));
  }
  return A;
}

Eigen::VectorXd read_x0(const sim::Table& t, Eigen::Index n) {
  if (!t.has("x0")) return Eigen::VectorXd::Zero(n);
  Eigen::VectorXd x0 = t.vector("x0");
  if (x0.size() != n) t.fail("x0", fmt::format("expected {} entries (the state size), got {}", n, x0.size()));
  return x0;
}

LinearPlant read_lti(const sim::Table& t, double /*period*/) {
  LinearPlant p;
  p.A = read_square(t, "A");
  const Eigen::Index n = p.A.rows();
  p.Bu = t.has("Bu") ? t.matrix("Bu") : Eigen::MatrixXd::Zero(n, 0);
  if (p.Bu.rows() != n) sim::require_shape(t, "Bu", p.Bu, n, p.Bu.cols());
  p.Bw = t.has("Bw") ? t.matrix("Bw") : Eigen::MatrixXd::Identity(n, n);
  if (p.Bw.rows() != n) sim::require_shape(t, "Bw", p.Bw, n, p.Bw.cols());
  p.W = t.matrix("W");
  sim::require_shape(t, "W", p.W, p.Bw.cols(), p.Bw.cols());
  sim::require_psd(t, "W", p.W);
  p.x0 = read_x0(t, n);
  return p;
}

LinearPlant read_lti_continuous(const sim::Table& t, double period) {
  const Eigen::MatrixXd Ac = read_square(t, "Ac");
  const Eigen::Index n = Ac.rows();
  Eigen::MatrixXd Bc = t.has("Bc") ? t.matrix("Bc") : Eigen::MatrixXd::Zero(n, 0);
  if (Bc.rows() != n) sim::require_shape(t, "Bc", Bc, n, Bc.cols());
  Eigen::MatrixXd Gc = t.has("Gc") ? t.matrix("Gc") : Eigen::MatrixXd::Identity(n, n);
  if (Gc.rows() != n) sim::require_shape(t, "Gc", Gc, n, Gc.cols());
  Eigen::MatrixXd Wc = t.matrix("Wc");
  sim::require_shape(t, "Wc", Wc, Gc.cols(), Gc.cols());
  sim::require_psd(t, "Wc", Wc);
  LinearPlant p = discretise(Ac, Bc, Gc, Wc, period);
  p.x0 = read_x0(t, n);
  return p;
}

// jump_linear: the lti keys are the base; each [[plant.mode]] overrides A, Bu, Bw, W.
LinearPlant read_jump_linear(const sim::Table& t, double period) {
  LinearPlant p = read_lti(t, period);
  const Eigen::Index n = p.n();
  const auto tables = t.tables("mode");
  if (tables.size() < 2 || tables.size() > 64) {
    t.fail("mode", fmt::format("expected 2..64 [[plant.mode]] tables, got {}", tables.size()));
  }
  for (const sim::Table& m : tables) {
    PlantMode pm{p.A, p.Bu, p.Bw, p.W};
    if (m.has("A")) {
      pm.A = m.matrix("A");
      sim::require_shape(m, "A", pm.A, n, n);
    }
    if (m.has("Bu")) {
      pm.Bu = m.matrix("Bu");
      sim::require_shape(m, "Bu", pm.Bu, n, p.nu());
    }
    if (m.has("Bw")) {
      pm.Bw = m.matrix("Bw");
      sim::require_shape(m, "Bw", pm.Bw, n, p.nw());
    }
    if (m.has("W")) {
      pm.W = m.matrix("W");
      sim::require_shape(m, "W", pm.W, p.nw(), p.nw());
      sim::require_psd(m, "W", pm.W);
    }
    m.finish();
    p.modes.push_back(std::move(pm));
  }
  const auto s = static_cast<Eigen::Index>(p.modes.size());
  p.mode_transition = t.matrix("transition");
  sim::require_shape(t, "transition", p.mode_transition, s, s);
  for (Eigen::Index i = 0; i < s; ++i) {
    const auto row = p.mode_transition.row(i);
    if (row.minCoeff() < 0.0 || std::abs(row.sum() - 1.0) > 1e-9) {
      t.fail("transition", fmt::format("expected non-negative rows summing to 1, row {} sums to {}", i, row.sum()));
    }
  }
  if (t.has("initial_mode")) {
    p.mode_initial = t.vector("initial_mode");
    if (p.mode_initial.size() != s || p.mode_initial.minCoeff() < 0.0 || std::abs(p.mode_initial.sum() - 1.0) > 1e-9) {
      t.fail("initial_mode", fmt::format("expected {} non-negative entries summing to 1", s));
    }
  } else {
    p.mode_initial = stationary_law(p.mode_transition);
  }
  return p;
}

}  // namespace

Eigen::VectorXd stationary_law(const Eigen::MatrixXd& transition) {
  const Eigen::Index n = transition.rows();
  Eigen::MatrixXd m(n + 1, n);
  m.topRows(n) = transition.transpose() - Eigen::MatrixXd::Identity(n, n);
  m.row(n).setOnes();
  Eigen::VectorXd rhs = Eigen::VectorXd::Zero(n + 1);
  rhs(n) = 1.0;
  Eigen::VectorXd pi = m.completeOrthogonalDecomposition().solve(rhs).cwiseMax(0.0);
  return pi / pi.sum();
}

void register_plants(PlantRegistry& registry) {
  registry.add("lti", "discrete LTI plant: A, Bu (optional), Bw (default I), W, x0", read_lti);
  registry.add("lti_continuous",
               "continuous LTI plant discretised at the period: Ac, Bc, Gc (default I), Wc "
               "(noise intensity), x0 (ZOH, Van Loan)",
               read_lti_continuous);
  registry.add("jump_linear",
               "Markov jump linear plant: the lti keys as base, [[plant.mode]] tables overriding A, Bu, "
               "Bw, W, transition (mode chain), initial_mode (default: stationary)",
               read_jump_linear);
}

}  // namespace ncosim::models
