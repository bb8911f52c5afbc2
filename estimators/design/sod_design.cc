// estimators/design/sod_design.cc — LMIs (11) and (20) of the send-on-delta paper, z~0 and
// the greedy co-design.
#include "estimators/design/sod_design.h"

#include <chrono>
#include <cmath>
#include <limits>

#include "estimators/design/sod_bounds.h"

namespace ncosim::est::sod {

using Eigen::MatrixXd;
using Eigen::VectorXd;

Eigen::VectorXd SodSystem::eta(unsigned j) const {
  VectorXd e = VectorXd::Zero(ny());
  for (Eigen::Index s = 0; s < ns(); ++s) {
    if ((j >> s) & 1U) {
      const auto s0 = sensor_rows[static_cast<std::size_t>(s)],
                 s1 = sensor_rows[static_cast<std::size_t>(s) + 1];
      e.segment(s0, s1 - s0).setOnes();
    }
  }
  return e;
}

std::vector<double> pattern_probabilities(const Eigen::VectorXd& beta) {
  const auto ns = static_cast<unsigned>(beta.size());
  std::vector<double> p(std::size_t{1} << ns, 1.0);
  for (unsigned j = 0; j < p.size(); ++j) {
    for (unsigned s = 0; s < ns; ++s) p[j] *= ((j >> s) & 1U) ? beta(s) : 1.0 - beta(s);
  }
  return p;
}

namespace {

lmi::Expr zeros(Eigen::Index r, Eigen::Index c) { return MatrixXd::Zero(r, c); }

// diag(g_1, ..., g_m) of scalar variables.
lmi::Expr diag_of(const std::vector<lmi::Var>& g) {
  const auto m = static_cast<Eigen::Index>(g.size());
  lmi::Expr e = zeros(m, m);
  for (Eigen::Index i = 0; i < m; ++i) {
    const MatrixXd ei = MatrixXd::Identity(m, m).col(i);
    e += ei * g[static_cast<std::size_t>(i)] * MatrixXd(ei.transpose());
  }
  return e;
}

// The symmetric block matrix whose lower triangle (row i: blocks 0..i) is given.
lmi::Expr symmetric_from_lower(const std::vector<std::vector<lmi::Expr>>& lower) {
  const std::size_t m = lower.size();
  std::vector<std::vector<lmi::Expr>> rows(m, std::vector<lmi::Expr>(m));
  for (std::size_t i = 0; i < m; ++i) {
    for (std::size_t j = 0; j <= i; ++j) {
      rows[i][j] = lower[i][j];
      if (j < i) rows[j][i] = lower[i][j].transpose();
    }
  }
  return lmi::block(rows);
}

struct Vars {
  std::vector<lmi::Var> Q, P;
  std::vector<lmi::Expr> X;
  lmi::Var gw;
  std::vector<lmi::Var> gv, gd;
};

// `needed` (jump gains, empty: all): patterns that occur with positive probability somewhere.
// A pattern that never occurs gets no variables of its own (they would appear in no LMI, an
// ill-posed problem): it shares the gain of the first pattern that occurs.
Vars make_vars(lmi::Problem& prob, const SodSystem& sys, std::size_t patterns, bool jump,
               std::size_t nP, bool with_delta, bool all_delivered = false,
               const std::vector<bool>& needed = {}) {
  const int n = static_cast<int>(sys.A.rows());
  const int ny = static_cast<int>(sys.ny());
  Vars v;
  std::size_t first = 0;
  while (!needed.empty() && first < patterns && !needed[first]) ++first;
  if (first == patterns) first = 0;
  auto own = [&](std::size_t j) {
    return jump ? needed.empty() || needed[j] || j == first : j == 0;
  };
  for (std::size_t j = 0; j < patterns; ++j) {
    if (own(j)) {
      v.Q.push_back(prob.full(n, n, "Q" + std::to_string(j)));
      // Gain columns of a periodic sensor that did not deliver in pattern j are 0.
      const Eigen::VectorXd eta = sys.eta(static_cast<unsigned>(j));
      std::vector<bool> live(static_cast<std::size_t>(ny), true);
      bool all = true;
      for (Eigen::Index s = 0; s < sys.ns(); ++s) {
        const bool sod =
            sys.send_on_delta.empty() || sys.send_on_delta[static_cast<std::size_t>(s)];
        for (Eigen::Index i = sys.sensor_rows[static_cast<std::size_t>(s)];
             i < sys.sensor_rows[static_cast<std::size_t>(s) + 1]; ++i) {
          live[static_cast<std::size_t>(i)] = sod || eta(i) > 0.5;
          all = all && live[static_cast<std::size_t>(i)];
        }
      }
      if (all || !jump || all_delivered) {
        v.X.emplace_back(prob.full(n, ny, "X" + std::to_string(j)));
      } else {
        lmi::Expr X = MatrixXd::Zero(n, ny);
        for (int i = 0; i < ny; ++i) {
          if (!live[static_cast<std::size_t>(i)]) continue;
          const MatrixXd ei = MatrixXd::Identity(ny, ny).row(i);
          X += prob.full(n, 1, "X" + std::to_string(j) + "_" + std::to_string(i)) * ei;
        }
        v.X.push_back(X);
      }
    } else {
      // Shares pattern 0's (constant gain) or, below, the first occurring pattern's.
      v.Q.push_back(v.Q.empty() ? lmi::Var{} : v.Q.front());
      v.X.push_back(v.X.empty() ? lmi::Expr{} : v.X.front());
    }
  }
  for (std::size_t j = 0; j < patterns; ++j) {
    if (!own(j) && jump) {
      v.Q[j] = v.Q[first];
      v.X[j] = v.X[first];
    }
  }
  for (std::size_t j = 0; j < nP; ++j) v.P.push_back(prob.symmetric(n, "P" + std::to_string(j)));
  v.gw = prob.symmetric(1, "gamma_w");
  for (int i = 0; i < ny; ++i) {
    v.gv.push_back(prob.symmetric(1, "gamma_v" + std::to_string(i)));
    if (with_delta) v.gd.push_back(prob.symmetric(1, "gamma_d" + std::to_string(i)));
  }
  return v;
}

lmi::LinearForm bound_form(const SodSystem& sys, const Vars& v, const VectorXd& sigma2) {
  lmi::LinearForm f = (sys.w_rms * sys.w_rms) * lmi::trace(v.gw);
  for (std::size_t i = 0; i < v.gv.size(); ++i) {
    const double r = sys.v_rms(static_cast<Eigen::Index>(i));
    f = f + (r * r) * lmi::trace(v.gv[i]);
  }
  for (std::size_t i = 0; i < v.gd.size(); ++i)
    f = f + sigma2(static_cast<Eigen::Index>(i)) * lmi::trace(v.gd[i]);
  return f;
}

SodDesignResult collect(const lmi::Solution& sol, const Vars& v, std::size_t patterns,
                        const lmi::LinearForm& f, int lmis) {
  SodDesignResult r;
  r.lmis = lmis;
  r.size = sol.size;
  r.seconds = sol.seconds;
  r.ok = sol.ok();
  r.status = r.ok ? "ok" : lmi::to_string(sol.status);
  if (!r.ok) {
    r.message = sol.message;
    return r;
  }
  r.bound = sol.value(f);
  r.gamma_w = sol.value(v.gw)(0, 0);
  r.gamma_v.resize(static_cast<Eigen::Index>(v.gv.size()));
  for (std::size_t i = 0; i < v.gv.size(); ++i)
    r.gamma_v(static_cast<Eigen::Index>(i)) = sol.value(v.gv[i])(0, 0);
  r.gamma_delta.resize(static_cast<Eigen::Index>(v.gd.size()));
  for (std::size_t i = 0; i < v.gd.size(); ++i)
    r.gamma_delta(static_cast<Eigen::Index>(i)) = sol.value(v.gd[i])(0, 0);
  for (std::size_t j = 0; j < patterns; ++j) {
    const MatrixXd Q = sol.value(v.Q[j]);
    const MatrixXd X = sol.value(v.X[j]);
    r.gains.push_back(Q.fullPivLu().solve(X));  // L_j = Q_j^-1 X_j
    r.Q.push_back(Q);
    r.X.push_back(X);
  }
  for (const auto& P : v.P) r.P.push_back(sol.value(P));
  return r;
}

// The pattern probabilities at each vertex of the box beta_s in {beta'_s, 1} (or only at beta'),
// and in `needed` the patterns with positive probability at some vertex (with delta = 0 every
// sensor always sends, and only the all-delivered pattern occurs).
std::vector<std::vector<double>> vertex_probabilities(const SodSystem& sys,
                                                      const SodDesignSpec& spec,
                                                      std::size_t patterns,
                                                      std::vector<bool>& needed) {
  std::vector<std::vector<double>> vertex_p;
  needed.assign(patterns, false);
  const auto ns = static_cast<unsigned>(sys.ns());
  const unsigned vertices = spec.vertices == Vertices::kAll ? 1U << ns : 1U;
  for (unsigned c = 0; c < vertices; ++c) {
    VectorXd beta = spec.beta_lower;
    for (unsigned s = 0; s < ns; ++s) {
      if ((c >> s) & 1U) beta(s) = 1.0;
    }
    vertex_p.push_back(pattern_probabilities(beta));
    for (std::size_t j = 0; j < patterns; ++j) needed[j] = needed[j] || vertex_p.back()[j] > 0.0;
  }
  return vertex_p;
}

// The blocks of (11) and (20) per pattern j: Abar = (Q - X C) A, Bbar = (Q - X C) Bw, -X',
// -(I - diag(eta_j)) X' and Q + Q'.
struct PatternBlocks {
  std::vector<lmi::Expr> Abar, Bbar, Xt, Xeta, QQ;
};
PatternBlocks pattern_blocks(const SodSystem& sys, const Vars& v, std::size_t patterns) {
  const MatrixXd I = MatrixXd::Identity(sys.ny(), sys.ny());
  PatternBlocks pb;
  for (std::size_t j = 0; j < patterns; ++j) {
    const lmi::Expr qxc = lmi::Expr(v.Q[j]) - v.X[j] * sys.C;
    pb.Abar.push_back(qxc * sys.A);
    pb.Bbar.push_back(qxc * sys.Bw);
    pb.Xt.push_back(-v.X[j].transpose());
    const MatrixXd Ieta = I - MatrixXd(sys.eta(static_cast<unsigned>(j)).asDiagonal());
    pb.Xeta.push_back(-(Ieta * v.X[j].transpose()));
    pb.QQ.push_back(lmi::Expr(v.Q[j]) + lmi::Expr(v.Q[j]).transpose());
  }
  return pb;
}

// The diagonal blocks of the noise variables: Gw (nw x nw), Gv, Gd (ny x ny).
struct NoiseBlocks {
  lmi::Expr Gw, Gv, Gd;
};

// (11) for every (j, k): blocks x~ (P_j), x~ (P_k - Cz'Cz), w, v, delta. Returns the LMIs added.
int add_deterministic_lmis(lmi::Problem& prob, const SodSystem& sys, const Vars& v,
                           const PatternBlocks& pb, const NoiseBlocks& g, std::size_t patterns,
                           double margin) {
  const Eigen::Index n = sys.A.rows(), nw = sys.Bw.cols(), ny = sys.ny();
  const MatrixXd CzCz = sys.Cz.transpose() * sys.Cz;
  int lmis = 0;
  for (std::size_t j = 0; j < patterns; ++j) {
    for (std::size_t k = 0; k < patterns; ++k) {
      prob.add(lmi::lmi(symmetric_from_lower(
                            {{pb.QQ[j] - v.P[j]},
                             {pb.Abar[j].transpose(), lmi::Expr(v.P[k]) - CzCz},
                             {pb.Bbar[j].transpose(), zeros(nw, n), g.Gw},
                             {pb.Xt[j], zeros(ny, n), zeros(ny, nw), g.Gv},
                             {pb.Xeta[j], zeros(ny, n), zeros(ny, nw), zeros(ny, ny), g.Gd}}) > 0,
                        margin));
      ++lmis;
    }
  }
  return lmis;
}

// (20) at one vertex of the box (pattern probabilities p), zero-probability pattern blocks
// dropped.
void add_stochastic_lmi(lmi::Problem& prob, const SodSystem& sys, const Vars& v,
                        const PatternBlocks& pb, const NoiseBlocks& g, const std::vector<double>& p,
                        double margin) {
  const Eigen::Index n = sys.A.rows(), nw = sys.Bw.cols(), ny = sys.ny();
  const MatrixXd CzCz = sys.Cz.transpose() * sys.Cz;
  std::vector<std::size_t> live;
  for (std::size_t j = 0; j < p.size(); ++j) {
    if (p[j] > 0.0) live.push_back(j);
  }
  const auto L = static_cast<Eigen::Index>(live.size());
  // Rows: L blocks of n (M1), then n (P - Cz'Cz), nw, ny, ny.
  std::vector<std::vector<lmi::Expr>> lower;
  for (Eigen::Index a = 0; a < L; ++a) {
    std::vector<lmi::Expr> row;
    for (Eigen::Index b = 0; b < a; ++b) row.push_back(zeros(n, n));
    const std::size_t j = live[static_cast<std::size_t>(a)];
    row.push_back(p[j] * (pb.QQ[j] - v.P[0]));
    lower.push_back(std::move(row));
  }
  std::vector<lmi::Expr> r2, r3, r4, r5;
  for (const std::size_t j : live) {
    r2.push_back(p[j] * pb.Abar[j].transpose());
    r3.push_back(p[j] * pb.Bbar[j].transpose());
    r4.push_back(p[j] * pb.Xt[j]);
    r5.push_back(p[j] * pb.Xeta[j]);
  }
  r2.push_back(lmi::Expr(v.P[0]) - CzCz);
  r3.push_back(zeros(nw, n));
  r3.push_back(g.Gw);
  r4.push_back(zeros(ny, n));
  r4.push_back(zeros(ny, nw));
  r4.push_back(g.Gv);
  r5.push_back(zeros(ny, n));
  r5.push_back(zeros(ny, nw));
  r5.push_back(zeros(ny, ny));
  r5.push_back(g.Gd);
  lower.push_back(r2);
  lower.push_back(r3);
  lower.push_back(r4);
  lower.push_back(r5);
  prob.add(lmi::lmi(symmetric_from_lower(lower) > 0, margin));
}

}  // namespace

SodDesignResult design_sod(const SodSystem& sys, const SodDesignSpec& spec) {
  const Eigen::Index nw = sys.Bw.cols();
  const std::size_t patterns = std::size_t{1} << sys.ns();
  lmi::Problem prob;
  const bool det = spec.approach == Approach::kDeterministic;
  // Stochastic design: the vertices' pattern probabilities and the patterns they need.
  std::vector<std::vector<double>> vertex_p;
  std::vector<bool> needed;
  if (!det) vertex_p = vertex_probabilities(sys, spec, patterns, needed);
  const Vars v = make_vars(prob, sys, patterns, spec.jump, det ? patterns : 1, true, false, needed);
  const NoiseBlocks g{diag_of(std::vector<lmi::Var>(static_cast<std::size_t>(nw), v.gw)),
                      diag_of(v.gv), diag_of(v.gd)};
  const PatternBlocks pb = pattern_blocks(sys, v, patterns);
  int lmis = 0;
  if (det) {
    lmis = add_deterministic_lmis(prob, sys, v, pb, g, patterns, spec.margin);
  } else {
    for (const std::vector<double>& p : vertex_p) {
      add_stochastic_lmi(prob, sys, v, pb, g, p, spec.margin);
      ++lmis;
    }
  }
  const lmi::LinearForm f = bound_form(sys, v, spec.sigma2_delta);
  prob.minimize(f);
  return collect(prob.solve(), v, patterns, f, lmis);
}

SodDesignResult design_all_measurements(const SodSystem& sys) {
  const Eigen::Index n = sys.A.rows(), nw = sys.Bw.cols(), ny = sys.ny();
  lmi::Problem prob;
  const Vars v = make_vars(prob, sys, 1, true, 1, false, /*all_delivered=*/true);
  const lmi::Expr Gv = diag_of(v.gv);
  const lmi::Expr Gw = diag_of(std::vector<lmi::Var>(static_cast<std::size_t>(nw), v.gw));
  const lmi::Expr qxc = lmi::Expr(v.Q[0]) - v.X[0] * sys.C;  // X[0]: all sensors delivered
  prob.add(
      lmi::lmi(symmetric_from_lower(
                   {{lmi::Expr(v.Q[0]) + lmi::Expr(v.Q[0]).transpose() - v.P[0]},
                    {(qxc * sys.A).transpose(), lmi::Expr(v.P[0]) - sys.Cz.transpose() * sys.Cz},
                    {(qxc * sys.Bw).transpose(), zeros(nw, n), Gw},
                    {-v.X[0].transpose(), zeros(ny, n), zeros(ny, nw), Gv}}) > 0,
               1e-7));
  const lmi::LinearForm f = bound_form(sys, v, VectorXd());
  prob.minimize(f);
  return collect(prob.solve(), v, 1, f, 1);
}

Eigen::MatrixXd psi_at(const SodSystem& sys, const SodDesignResult& r, const Eigen::VectorXd& beta,
                       const Eigen::VectorXd&) {
  const Eigen::Index n = sys.A.rows(), nw = sys.Bw.cols(), ny = sys.ny();
  const std::vector<double> p = pattern_probabilities(beta);
  const auto q = static_cast<Eigen::Index>(p.size());
  const Eigen::Index N = q * n + n + nw + 2 * ny;
  MatrixXd Psi = MatrixXd::Zero(N, N);
  const MatrixXd& P = r.P.front();
  const Eigen::Index o2 = q * n, o3 = o2 + n, o4 = o3 + nw, o5 = o4 + ny;
  for (Eigen::Index j = 0; j < q; ++j) {
    const double pj = p[static_cast<std::size_t>(j)];
    const MatrixXd& Q = r.Q[static_cast<std::size_t>(j)];
    const MatrixXd& X = r.X[static_cast<std::size_t>(j)];
    const MatrixXd qxc = Q - X * sys.C;
    const MatrixXd Ieta =
        MatrixXd::Identity(ny, ny) - MatrixXd(sys.eta(static_cast<unsigned>(j)).asDiagonal());
    Psi.block(j * n, j * n, n, n) = pj * (Q + Q.transpose() - P);
    Psi.block(o2, j * n, n, n) = pj * (qxc * sys.A).transpose();
    Psi.block(o3, j * n, nw, n) = pj * (qxc * sys.Bw).transpose();
    Psi.block(o4, j * n, ny, n) = -pj * X.transpose();
    Psi.block(o5, j * n, ny, n) = -pj * Ieta * X.transpose();
  }
  Psi.block(o2, o2, n, n) = P - sys.Cz.transpose() * sys.Cz;
  Psi.block(o3, o3, nw, nw) = r.gamma_w * MatrixXd::Identity(nw, nw);
  Psi.block(o4, o4, ny, ny) = r.gamma_v.asDiagonal();
  Psi.block(o5, o5, ny, ny) = r.gamma_delta.asDiagonal();
  return Psi.selfadjointView<Eigen::Lower>();
}

// ---- co-design ------------------------------------------------------------------------------

void codesign_bounds(const CodesignSpec& spec, const Eigen::VectorXd& delta,
                     Eigen::VectorXd& sigma2, Eigen::VectorXd& beta) {
  const Eigen::Index m = delta.size();
  sigma2.resize(m);
  beta.resize(m);
  for (Eigen::Index i = 0; i < m; ++i) {
    if (spec.approach == Approach::kDeterministic) {
      sigma2(i) = spec.sigma2_factor * delta(i) * delta(i);
      beta(i) = 0.0;
    } else if (spec.assumption == Assumption::kUniform) {
      sigma2(i) = uniform_sigma2(delta(i), spec.r(i));
      beta(i) = uniform_beta(delta(i), spec.r(i));
    } else {
      sigma2(i) = gaussian_sigma2(delta(i), spec.r(i));
      beta(i) = gaussian_beta(delta(i), spec.r(i));
    }
  }
}

double codesign_cost(const CodesignSpec& spec, const Eigen::VectorXd& delta) {
  if (spec.approach == Approach::kDeterministic)
    return cost_deterministic(delta, spec.g.size() ? spec.g : spec.r);
  VectorXd s2, beta;
  codesign_bounds(spec, delta, s2, beta);
  return cost_stochastic(beta);
}

namespace {

// Delta_i that makes the cost equal `target` with the other thresholds fixed; NaN if none.
double threshold_for_cost(const CodesignSpec& spec, const VectorXd& delta, Eigen::Index i,
                          double target) {
  if (spec.approach == Approach::kDeterministic) {
    const VectorXd g = spec.g.size() ? spec.g : spec.r;
    double rest = 0.0;
    for (Eigen::Index j = 0; j < delta.size(); ++j) {
      if (j != i) rest += g(j) / delta(j);
    }
    const double share = target - rest;
    return share > 0.0 ? g(i) / share : std::nan("");
  }
  VectorXd s2, beta;
  codesign_bounds(spec, delta, s2, beta);
  double others = 1.0;  // prod over j != i of (1 - beta_j)
  for (Eigen::Index j = 0; j < delta.size(); ++j) {
    if (j != i) others *= 1.0 - beta(j);
  }
  const double bi = 1.0 - (1.0 - target) / others;
  if (!(bi >= 0.0) || bi > 1.0) return std::nan("");
  return spec.assumption == Assumption::kUniform ? uniform_delta_for_beta(bi, spec.r(i))
                                                 : gaussian_delta_for_beta(bi, spec.r(i));
}

}  // namespace

CodesignResult codesign(const SodSystem& sys, const CodesignSpec& spec,
                        const std::function<void(const CodesignStep&)>& progress) {
  const auto t0 = std::chrono::steady_clock::now();
  CodesignResult out;
  auto solve = [&](const VectorXd& delta) {
    SodDesignSpec ds;
    ds.approach = spec.approach;
    ds.jump = spec.jump;
    ds.vertices = spec.vertices;
    VectorXd beta;
    codesign_bounds(spec, delta, ds.sigma2_delta, beta);
    ds.beta_lower = beta;
    SodDesignResult r = design_sod(sys, ds);
    ++out.lmi_problems;
    out.lmi_seconds += r.seconds;
    return r;
  };
  VectorXd delta = spec.delta0;
  SodDesignResult current = solve(delta);
  double cost = codesign_cost(spec, delta);
  if (!current.ok || current.bound >= spec.target) {
    out.status = "start_infeasible";
    out.delta = delta;
    out.design = current;
    out.cost = cost;
    out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return out;
  }
  out.path.push_back({0, delta, cost, current.bound});
  if (progress) progress(out.path.back());
  for (int it = 1; it <= spec.max_iterations; ++it) {
    const double target_cost =
        spec.relative_step ? cost * (1.0 - spec.epsilon) : cost - spec.epsilon;
    double best = std::numeric_limits<double>::infinity();
    VectorXd best_delta;
    SodDesignResult best_design;
    for (Eigen::Index i = 0; i < delta.size(); ++i) {
      const double di = threshold_for_cost(spec, delta, i, target_cost);
      if (!std::isfinite(di)) continue;
      VectorXd cand = delta;
      cand(i) = di;
      SodDesignResult r = solve(cand);
      if (r.ok && r.bound < best) {
        best = r.bound;
        best_delta = cand;
        best_design = std::move(r);
      }
    }
    if (!(best < spec.target)) break;
    delta = best_delta;
    current = std::move(best_design);
    cost = codesign_cost(spec, delta);
    out.iterations = it;
    out.path.push_back({it, delta, cost, current.bound});
    if (progress) progress(out.path.back());
  }
  out.delta = delta;
  out.design = std::move(current);
  out.cost = cost;
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

}  // namespace ncosim::est::sod
