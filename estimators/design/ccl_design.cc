// estimators/design/ccl_design.cc — CCL + bisection for problem (27) (see ccl_design.h).
#include "estimators/design/ccl_design.h"

#include <Eigen/Eigenvalues>
#include <cmath>
#include <cstdio>
#include <limits>

namespace ncosim::est {

namespace {

using Eigen::MatrixXd;

// Z with M = Z Z' (columns of negligible eigenvalues dropped; M symmetric PSD).
MatrixXd psd_factor(const MatrixXd& M) {
  Eigen::SelfAdjointEigenSolver<MatrixXd> es(0.5 * (M + M.transpose()));
  const double top = std::max(es.eigenvalues().cwiseAbs().maxCoeff(), 1e-300);
  std::vector<Eigen::Index> keep;
  for (Eigen::Index i = 0; i < M.rows(); ++i)
    if (es.eigenvalues()(i) > 1e-12 * top) keep.push_back(i);
  MatrixXd Z(M.rows(), static_cast<Eigen::Index>(keep.size()));
  for (std::size_t c = 0; c < keep.size(); ++c)
    Z.col(static_cast<Eigen::Index>(c)) = es.eigenvectors().col(keep[c]) * std::sqrt(es.eigenvalues()(keep[c]));
  return Z;
}

struct CclTerm {
  int N;
  std::uint64_t pattern;
  double w;
  int group;
};

struct Setup {
  const ExtendedModel& ext;
  const std::vector<double>& prob;
  int Nbar;
  Grouping grouping;
  double p0;
  std::vector<MatrixXd> Apow, noise_factor;  // noise_factor[N]: factor of S_W,N (tail: of the tail noise)
  std::vector<CclTerm> terms;
  std::vector<MatrixXd> select;  // per group: rows of the gain that are variables (|U| x nmb), empty: none
  std::size_t groups = 0;
};

struct Built {
  lmi::Problem prob;
  lmi::Var S, Q, R;
  lmi::Expr P;
  std::vector<lmi::Var> L;  // per group with a variable (index by group; id -1 when none)
};

Built build(const Setup& s, double gamma) {
  const ExtendedModel& ext = s.ext;
  const Eigen::Index nb = ext.nb;
  const MatrixXd I = MatrixXd::Identity(nb, nb);
  Built b;
  b.S = b.prob.symmetric(static_cast<int>(nb), "S_P");
  b.Q = b.prob.symmetric(static_cast<int>(nb), "Q");
  b.R = b.prob.symmetric(static_cast<int>(nb), "R");
  b.P = lmi::Expr(b.S) - s.p0 * (ext.A * b.S * MatrixXd(ext.A.transpose()));  // eq. (19)
  b.L.resize(s.groups);
  for (std::size_t g = 0; g < s.groups; ++g)
    if (s.select[g].rows() > 0)
      b.L[g] = b.prob.full(static_cast<int>(nb), static_cast<int>(s.select[g].rows()), "L" + std::to_string(g));
  lmi::Expr sumY = lmi::Expr(MatrixXd::Zero(nb, nb));
  // Terms in chunks of bounded LMI size, each with its own Y (CSDP's cost grows with the
  // cube of a block's size; a slack Y per chunk keeps the problem exact).
  constexpr Eigen::Index kMaxBlock = 40;
  std::vector<std::vector<lmi::Expr>> B, D;  // per chunk
  std::vector<Eigen::Index> chunk_size;
  int chunk_N = 0;
  auto flush = [&] {
    if (B.empty() || B.back().empty()) return;
    const std::size_t c = B.size() - 1;
    lmi::Var Y = b.prob.symmetric(static_cast<int>(nb), "Y" + std::to_string(c));
    sumY += Y;
    std::vector<std::vector<lmi::Expr>> rows(B[c].size() + 1);
    rows[0].push_back(Y);
    for (auto& e : B[c]) rows[0].push_back(e);
    for (std::size_t i = 0; i < B[c].size(); ++i) {
      rows[i + 1].push_back(B[c][i].transpose());
      for (std::size_t j = 0; j < B[c].size(); ++j)
        rows[i + 1].push_back(i == j ? D[c][i] : lmi::Expr(MatrixXd::Zero(D[c][i].rows(), D[c][j].cols())));
    }
    b.prob.add(lmi::lmi(lmi::block(rows) >= 0, -1.0, "(25) N=" + std::to_string(chunk_N) + " part " + std::to_string(c)));
  };
  for (const CclTerm& term : s.terms) {
    const CclTerm* t = &term;
    const int N = t->N;
    const bool tail = N == s.Nbar;
    const MatrixXd& AN = s.Apow[N];
    const MatrixXd& Zw = s.noise_factor[N];
    const MatrixXd mask = ext.row_mask(t->pattern).asDiagonal();
    const MatrixXd& E = s.select[t->group];
    const MatrixXd Zv = psd_factor(E * mask * ext.V * mask * E.transpose());
    const Eigen::Index size = nb + Zw.cols() + Zv.cols();
    if (B.empty() || N != chunk_N || chunk_size.back() + size > kMaxBlock) {
      flush();
      B.emplace_back();
      D.emplace_back();
      chunk_size.push_back(nb);
      chunk_N = N;
    }
    chunk_size.back() += size;
    const lmi::Expr G = b.L[t->group] * MatrixXd(E * mask);  // L eta (nb x nmb)
    const lmi::Expr F = lmi::Expr(I) - G * ext.C;
    const double sw = std::sqrt(t->w);
    B.back().push_back(tail ? std::sqrt(t->w * (1.0 - s.p0)) * (F * AN) : sw * (F * AN));
    D.back().push_back(tail ? lmi::Expr(b.R) : lmi::Expr(b.Q));
    if (Zw.cols() > 0) {
      B.back().push_back(sw * (F * Zw));
      D.back().push_back(MatrixXd(MatrixXd::Identity(Zw.cols(), Zw.cols())));
    }
    if (Zv.cols() > 0) {
      B.back().push_back(sw * (b.L[t->group] * Zv));
      D.back().push_back(MatrixXd(MatrixXd::Identity(Zv.cols(), Zv.cols())));
    }
  }
  flush();
  b.prob.add(lmi::lmi(b.P - sumY >= 0, -1.0, "P >= sum Y"));
  b.prob.add(lmi::lmi(lmi::block({{b.P, I}, {I, b.Q}}) >= 0, -1.0, "[P I; I Q]"));
  b.prob.add(lmi::lmi(lmi::block({{b.S, I}, {I, b.R}}) >= 0, -1.0, "[S I; I R]"));
  if (std::isfinite(gamma)) {
    // tr(P) = sum_i e_i' P e_i as a 1x1 expression.
    lmi::Expr tr = lmi::Expr(MatrixXd::Zero(1, 1));
    for (Eigen::Index i = 0; i < nb; ++i) tr += MatrixXd(I.row(i)) * b.P * MatrixXd(I.col(i));
    b.prob.add(lmi::lmi(tr <= MatrixXd::Constant(1, 1, gamma), -1.0, "tr(P) <= gamma"));
  }
  return b;
}

std::vector<MatrixXd> gains_of(const Setup& s, const Built& b, const lmi::Solution& sol) {
  std::vector<MatrixXd> gains(s.groups, MatrixXd::Zero(s.ext.nb, s.ext.nmb));
  for (std::size_t g = 0; g < s.groups; ++g)
    if (s.select[g].rows() > 0) gains[g] = sol.value(b.L[g]) * s.select[g];
  return gains;
}

}  // namespace

JumpDesign design_jump_ccl(const ExtendedModel& ext, const std::vector<double>& prob, int Nbar,
                           Grouping grouping, const CclOptions& opt, CclInfo* info_out) {
  CclInfo info;
  const Eigen::Index nb = ext.nb, nm = ext.nmb;
  const double p0 = prob[0];
  const int per_N = groups_per_N(grouping, ext);
  // Checks shared with the evaluation (p0 >= 1, p0 rho^2 >= 1): a zero-gain evaluation.
  const std::vector<MatrixXd> zero(static_cast<std::size_t>(per_N) * Nbar, MatrixXd::Zero(nb, nm));
  JumpDesign failed = evaluate_jump_gains(ext, prob, Nbar, grouping, zero);
  failed.stable = false;
  if (failed.status.rfind("unstable:", 0) == 0 || failed.status == "no_measurements") {
    if (info_out) *info_out = info;
    return failed;
  }
  failed.P.setConstant(std::nan(""));
  failed.Pt.setConstant(std::nan(""));

  Setup s{ext, prob, Nbar, grouping, p0, {}, {}, {}, {}, 0};
  s.Apow.resize(Nbar + 1);
  std::vector<MatrixXd> SW(Nbar + 1);
  s.Apow[0] = MatrixXd::Identity(nb, nb);
  SW[0] = MatrixXd::Zero(nb, nb);
  for (int N = 1; N <= Nbar; ++N) {
    s.Apow[N] = ext.A * s.Apow[N - 1];
    SW[N] = SW[N - 1] + s.Apow[N - 1] * ext.Q * s.Apow[N - 1].transpose();
  }
  const MatrixXd stein = stein_operator(ext.A, p0);
  const MatrixXd SWinf = stein_sum(stein, ext.Q);
  s.noise_factor.resize(Nbar + 1);
  for (int N = 1; N < Nbar; ++N) s.noise_factor[N] = psd_factor(SW[N]);
  s.noise_factor[Nbar] = psd_factor(SW[Nbar] + p0 * s.Apow[Nbar] * SWinf * s.Apow[Nbar].transpose());
  s.groups = static_cast<std::size_t>(per_N) * Nbar;
  std::vector<Eigen::VectorXd> used(s.groups, Eigen::VectorXd::Zero(nm));
  for (int N = 1; N <= Nbar; ++N) {
    const double wN = N < Nbar ? std::pow(p0, N - 1) : std::pow(p0, Nbar - 1) / (1.0 - p0);
    for (std::size_t m = 1; m < prob.size(); ++m) {
      if (prob[m] <= 0.0) continue;
      const int g = (N - 1) * per_N + group_of(grouping, ext, m);
      s.terms.push_back({N, m, wN * prob[m], g});
      used[g] = used[g].cwiseMax(ext.row_mask(m));
    }
  }
  s.select.resize(s.groups);
  for (std::size_t g = 0; g < s.groups; ++g) {
    const int k = static_cast<int>(used[g].sum());
    s.select[g] = MatrixXd::Zero(k, nm);
    for (Eigen::Index r = 0, i = 0; r < nm; ++r)
      if (used[g](r) > 0.0) s.select[g](i++, r) = 1.0;
  }

  lmi::Options lo;
  lo.verbose = opt.verbose;
  lo.max_iterations = opt.sdp_max_iterations;
  JumpDesign best = failed;
  double best_trP = std::numeric_limits<double>::infinity();
  auto solve = [&](Built& b) {
    b.prob.options() = lo;
    lmi::Solution sol = b.prob.solve();
    ++info.sdp_solves;
    if (opt.verbose) std::fputs(sol.log.c_str(), stderr);
    if (opt.verbose)
      std::fprintf(stderr, "sdp %d: %s obj %.6g %.3fs k=%d blocks=%d\n", info.sdp_solves, lmi::to_string(sol.status),
                   sol.objective, sol.seconds, sol.size.variables, sol.size.blocks);
    return sol;
  };
  // Gains of a solution: keep the best exact fixed point.
  auto consider = [&](const Built& b, const lmi::Solution& sol) {
    JumpDesign d = evaluate_jump_gains(ext, prob, Nbar, grouping, gains_of(s, b, sol));
    if (!d.stable) return std::numeric_limits<double>::infinity();
    const double tr = d.P.trace();
    if (tr < best_trP) {
      best_trP = tr;
      best = std::move(d);
    }
    return tr;
  };
  std::string fail_status;
  // CCL at gamma from a feasible point: true when gains with tr(P) <= gamma were found.
  auto ccl = [&](double gamma) {
    Built b = build(s, gamma);
    lmi::Solution sol = solve(b);  // step 2: a feasible point (no objective)
    if (!sol.ok()) {
      if (sol.status != lmi::Status::kInfeasible && fail_status.empty()) fail_status = lmi::to_string(sol.status);
      return false;
    }
    if (consider(b, sol) <= gamma) return true;
    double previous = std::numeric_limits<double>::infinity();
    for (int k = 0; k < opt.max_ccl_iterations; ++k) {
      const MatrixXd Pk = sol.value(b.P), Qk = sol.value(b.Q), Sk = sol.value(b.S), Rk = sol.value(b.R);
      b.prob.minimize(lmi::trace(Pk * lmi::Expr(b.Q)) + lmi::trace(Qk * b.P) + lmi::trace(Sk * lmi::Expr(b.R)) +
                      lmi::trace(Rk * lmi::Expr(b.S)));
      sol = solve(b);
      ++info.ccl_iterations;
      if (!sol.ok()) {
        if (fail_status.empty()) fail_status = lmi::to_string(sol.status);
        return false;
      }
      if (consider(b, sol) <= gamma * (1.0 + 1e-12)) return true;
      if (std::abs(previous - sol.objective) <= 1e-9 * std::abs(sol.objective)) return false;  // stalled
      previous = sol.objective;
    }
    return false;
  };

  // Relaxation (Q, R free): a lower bound on tr(P), and the SDP size.
  double lower = 0.0;
  {
    Built b = build(s, std::numeric_limits<double>::infinity());
    info.size = b.prob.size();
    b.prob.minimize(lmi::trace(b.P));
    const lmi::Solution sol = solve(b);
    if (!sol.ok()) {
      failed.status = lmi::to_string(sol.status);
      info.lmi_status = failed.status;
      if (info_out) *info_out = info;
      return failed;
    }
    lower = std::max(0.0, sol.objective);
    consider(b, sol);
  }
  if (!std::isfinite(best_trP)) ccl(std::numeric_limits<double>::infinity());
  if (!std::isfinite(best_trP)) {
    failed.status = fail_status.empty() ? "no_feasible_gains" : fail_status;
    info.lmi_status = fail_status.empty() ? "optimal" : fail_status;
    info.lower_bound = lower;
    if (info_out) *info_out = info;
    return failed;
  }
  // Bisection (section 4, steps 1-5).
  double upper = best_trP;
  for (; info.bisections < opt.max_bisections && upper - lower >= opt.relative_gap * upper; ++info.bisections) {
    const double gamma = 0.5 * (lower + upper);
    if (!ccl(gamma)) lower = gamma;
    upper = std::min(upper, best_trP);  // the best exact fixed point so far bounds the optimum
    if (opt.verbose) std::fprintf(stderr, "gamma %.6g -> [%.6g, %.6g] best %.6g\n", gamma, lower, upper, best_trP);
  }
  info.lower_bound = lower;
  info.upper_bound = best_trP;
  if (info_out) *info_out = info;
  return best;
}

}  // namespace ncosim::est
