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
    Z.col(static_cast<Eigen::Index>(c)) =
        es.eigenvectors().col(keep[c]) * std::sqrt(es.eigenvalues()(keep[c]));
  return Z;
}

// One Schur column group of LMI (25): coef (delta I - L E T Cbar) [A^N, Z_W] and, when Zv has
// columns, coef L Zv. A term of (18) for pattern eta is one piece with delta = 1, T = eta and
// coef = sqrt(w). A group of patterns sharing a gain can instead be written with the moments of
// its availability vector (exact): sum_m w_m F_m X F_m' = W [Fbar X Fbar' + sum_k H_k X H_k'] with
// Fbar = I - L E diag(mean) Cbar, H_k = L E diag(s_k) Cbar, Cov = sum_k s_k s_k', and the noise
// terms sum to W L E (Pi o V) E' L' (Pi = second moment): 1 + rank(Cov) pieces instead of one per
// pattern. The smaller form is used per group.
struct Piece {
  int N;
  int group;
  double coef;        // sqrt(weight) of the noise parts
  double coef_A;      // of the A^N part (the tail's extra (1 - p0) included)
  double delta;       // 1 for F-like pieces, 0 for the covariance pieces
  Eigen::VectorXd T;  // diagonal over the nmb fictitious sensors
  MatrixXd Zv;        // factor of the measurement-noise part (k columns) or empty
};

struct Setup {
  const ExtendedModel& ext;
  const std::vector<double>& prob;
  int Nbar;
  Grouping grouping;
  double p0;
  std::vector<MatrixXd> Apow,
      noise_factor;           // noise_factor[N]: factor of S_W,N (tail: of the tail noise)
  std::vector<Piece> pieces;  // ordered by N
  std::vector<MatrixXd>
      select;  // per group: rows of the gain that are variables (|U| x nmb), empty: none
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
      b.L[g] = b.prob.full(static_cast<int>(nb), static_cast<int>(s.select[g].rows()),
                           "L" + std::to_string(g));
  lmi::Expr sumY = lmi::Expr(MatrixXd::Zero(nb, nb));
  // Terms in chunks of bounded LMI size, each with its own Y (CSDP's cost grows with the
  // cube of a block's size; a slack Y per chunk keeps the problem exact).
  constexpr Eigen::Index kMaxBlock = 30;     // measured best over the A3 grid (12-100 tried)
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
        rows[i + 1].push_back(i == j ? D[c][i]
                                     : lmi::Expr(MatrixXd::Zero(D[c][i].rows(), D[c][j].cols())));
    }
    b.prob.add(lmi::lmi(lmi::block(rows) >= 0, -1.0,
                        "(25) N=" + std::to_string(chunk_N) + " part " + std::to_string(c)));
  };
  for (const Piece& pc : s.pieces) {
    const int N = pc.N;
    const bool tail = N == s.Nbar;
    const MatrixXd& AN = s.Apow[N];
    const MatrixXd& Zw = s.noise_factor[N];
    const MatrixXd& E = s.select[pc.group];
    const Eigen::Index size = nb + Zw.cols() + pc.Zv.cols();
    if (B.empty() || N != chunk_N || chunk_size.back() + size > kMaxBlock) {
      flush();
      B.emplace_back();
      D.emplace_back();
      chunk_size.push_back(nb);
      chunk_N = N;
    }
    chunk_size.back() += size;
    const lmi::Expr G = b.L[pc.group] * MatrixXd(E * pc.T.asDiagonal());  // L E T (nb x nmb)
    const lmi::Expr F = pc.delta * lmi::Expr(I) - G * ext.C;
    B.back().push_back(pc.coef_A * (F * AN));
    D.back().push_back(tail ? lmi::Expr(b.R) : lmi::Expr(b.Q));
    if (Zw.cols() > 0) {
      B.back().push_back(pc.coef * (F * Zw));
      D.back().push_back(MatrixXd(MatrixXd::Identity(Zw.cols(), Zw.cols())));
    }
    if (pc.Zv.cols() > 0) {
      B.back().push_back(pc.coef * (b.L[pc.group] * pc.Zv));
      D.back().push_back(MatrixXd(MatrixXd::Identity(pc.Zv.cols(), pc.Zv.cols())));
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

// The SDPs are built on the model with its noise covariances divided by this scale (then P, S_P
// scale by 1/scale, Q, R by scale and the gains are unchanged), so that their variables are
// of order one; every gain set is evaluated on the original model.
double noise_scale(const ExtendedModel& ext, const CclOptions& opt) {
  double scale = 1.0;
  if (opt.normalise) {
    const double t = (ext.Q.trace() + ext.V.trace()) / static_cast<double>(ext.nb + ext.nmb);
    if (t > 0.0 && std::isfinite(t)) scale = t;
  }
  return scale;
}

// Patterns of positive probability per group (the same for every N), returned, and the rows of
// each group's gain they use (s.select: the gain's rows that are variables).
std::vector<std::vector<std::uint64_t>> select_rows(Setup& s, const ExtendedModel& ext, int per_N) {
  const std::vector<double>& prob = s.prob;
  const Eigen::Index nm = ext.nmb;
  std::vector<std::vector<std::uint64_t>> members(static_cast<std::size_t>(per_N));
  std::vector<Eigen::VectorXd> used(s.groups, Eigen::VectorXd::Zero(nm));
  for (std::size_t m = 1; m < prob.size(); ++m) {
    if (prob[m] <= 0.0) continue;
    const int k = group_of(s.grouping, ext, m);
    members[static_cast<std::size_t>(k)].push_back(m);
    for (int N = 1; N <= s.Nbar; ++N) {
      if (history_weight(s.p0, N, s.Nbar) <= 0.0)
        continue;  // p0 = 0: no update ever waits N >= 2 periods
      const std::size_t g = static_cast<std::size_t>((N - 1) * per_N + k);
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
  return members;
}

// The pieces of LMI (25) for group g (history length N, weight wN) with patterns `pats`: one per
// pattern, or the moment form when it is smaller (see Piece).
std::vector<Piece> group_pieces(const Setup& s, const ExtendedModel& ext,
                                const std::vector<std::uint64_t>& pats, int N, int g,
                                bool group_moments) {
  const Eigen::Index nb = ext.nb, nm = ext.nmb;
  const double wN = history_weight(s.p0, N, s.Nbar);
  const double tailA =
      N < s.Nbar ? 1.0 : 1.0 - s.p0;  // the tail's A^N part is weighted by (1 - p0)
  const Eigen::Index zw = s.noise_factor[N].cols();
  const MatrixXd& V = s.ext.V;  // the normalised model's
  const MatrixXd& E = s.select[static_cast<std::size_t>(g)];
  // One piece per pattern ...
  std::vector<Piece> each;
  Eigen::Index each_size = 0;
  double W = 0.0;
  Eigen::VectorXd mean = Eigen::VectorXd::Zero(nm);
  MatrixXd second = MatrixXd::Zero(nm, nm);
  for (std::uint64_t m : pats) {
    const double w = wN * s.prob[m];
    const Eigen::VectorXd eta = ext.row_mask(m);
    const MatrixXd mask = eta.asDiagonal();
    Piece pc{N,
             g,
             std::sqrt(w),
             std::sqrt(w * tailA),
             1.0,
             eta,
             psd_factor(E * mask * V * mask * E.transpose())};
    each_size += nb + zw + pc.Zv.cols();
    each.push_back(std::move(pc));
    W += w;
    mean += w * eta;
    second += w * eta * eta.transpose();
  }
  // ... or the moment form.
  mean /= W;
  second /= W;
  const MatrixXd cov = second - mean * mean.transpose();
  const MatrixXd Sk = cov.isZero(0.0) ? MatrixXd(nm, 0) : psd_factor(cov);
  std::vector<Piece> moments;
  moments.push_back({N, g, std::sqrt(W), std::sqrt(W * tailA), 1.0, mean,
                     psd_factor(E * second.cwiseProduct(V) * E.transpose())});
  for (Eigen::Index c = 0; c < Sk.cols(); ++c)
    moments.push_back(
        {N, g, std::sqrt(W), std::sqrt(W * tailA), 0.0, Sk.col(c), MatrixXd(E.rows(), 0)});
  Eigen::Index moment_size = 0;
  for (const auto& pc : moments) moment_size += nb + zw + pc.Zv.cols();
  return group_moments && moment_size < each_size ? moments : each;
}

// The terms of (25) on the normalised model sext (its noise factors from h, whose powers of A
// are moved in), per history length N and group.
Setup make_setup(const ExtendedModel& ext, const ExtendedModel& sext,
                 const std::vector<double>& prob, int Nbar, Grouping grouping, HistoryTerms& h,
                 bool group_moments) {
  const int per_N = groups_per_N(grouping, ext);
  Setup s{sext, prob, Nbar, grouping, prob[0], {}, {}, {}, {}, 0};
  s.noise_factor.resize(Nbar + 1);
  for (int N = 1; N < Nbar; ++N) s.noise_factor[N] = psd_factor(h.SW[N]);
  s.noise_factor[Nbar] = psd_factor(h.tail_noise);
  s.Apow = std::move(h.Apow);
  s.groups = static_cast<std::size_t>(per_N) * Nbar;
  const auto members = select_rows(s, ext, per_N);
  for (int N = 1; N <= Nbar; ++N) {
    if (history_weight(s.p0, N, Nbar) <= 0.0)
      continue;  // its gains are never used: no variables, no terms
    for (int k = 0; k < per_N; ++k) {
      const auto& pats = members[static_cast<std::size_t>(k)];
      if (pats.empty()) continue;
      for (auto& pc : group_pieces(s, ext, pats, N, (N - 1) * per_N + k, group_moments))
        s.pieces.push_back(std::move(pc));
    }
  }
  return s;
}

// CCL (the paper's steps 2-4) inside a bisection on gamma = tr(P) (steps 1 and 5); every gain
// set found is evaluated exactly and the best exact fixed point is kept.
class CclSearch {
 public:
  CclSearch(const ExtendedModel& ext, const std::vector<double>& prob, int Nbar, Grouping grouping,
            const CclOptions& opt, double scale, const Setup& s, const MatrixXd& stein,
            const JumpDesign& failed)
      : ext_(ext),
        prob_(prob),
        Nbar_(Nbar),
        grouping_(grouping),
        opt_(opt),
        scale_(scale),
        s_(s),
        stein_(stein),
        failed_(failed),
        best_(failed) {
    lo_.verbose = opt.verbose;
    lo_.max_iterations = opt.sdp_max_iterations;
    lo_.tolerance = opt.sdp_tolerance;
  }

  JumpDesign run();
  const CclInfo& info() const { return info_; }

 private:
  lmi::Solution solve(Built& b);
  double consider(const Built& b, const lmi::Solution& sol);
  bool exact_linearisation_point(MatrixXd& Pk, MatrixXd& Qk, MatrixXd& Sk, MatrixXd& Rk) const;
  bool ccl(double gamma);
  bool first_gains(Built& first, double& lower);
  void bisect(double lower);

  const ExtendedModel& ext_;
  const std::vector<double>& prob_;
  const int Nbar_;
  const Grouping grouping_;
  const CclOptions& opt_;
  const double scale_;
  const Setup& s_;
  const MatrixXd& stein_;
  lmi::Options lo_;
  CclInfo info_;
  JumpDesign failed_;
  JumpDesign best_;
  double best_trP_ = std::numeric_limits<double>::infinity();
  JumpDesign s4_;
  bool s4_ok_ = false;
  std::string fail_status_;
};

lmi::Solution CclSearch::solve(Built& b) {
  b.prob.options() = lo_;
  lmi::Solution sol = b.prob.solve();
  ++info_.sdp_solves;
  if (opt_.verbose) std::fputs(sol.log.c_str(), stderr);
  if (opt_.verbose)
    std::fprintf(stderr, "sdp %d: %s obj %.6g %.3fs k=%d blocks=%d best %.8g\n", info_.sdp_solves,
                 lmi::to_string(sol.status), sol.objective, sol.seconds, sol.size.variables,
                 sol.size.blocks, best_trP_);
  return sol;
}

// Gains of a solution: keep the best exact fixed point. Its tr(P), infinity when unstable.
double CclSearch::consider(const Built& b, const lmi::Solution& sol) {
  JumpDesign d = evaluate_jump_gains(ext_, prob_, Nbar_, grouping_, gains_of(s_, b, sol));
  if (!d.stable) {
    if (opt_.verbose) std::fprintf(stderr, "gains: %s\n", d.status.c_str());
    return std::numeric_limits<double>::infinity();
  }
  const double tr = d.P.trace();
  if (tr < best_trP_) {
    best_trP_ = tr;
    best_ = std::move(d);
  }
  return tr;
}

// Step 2 from the best exact fixed point so far (before any, the S4 optimum): (25) holds there
// with Q = P^-1, R = S_P^-1. False when there is none, or when P is singular (e.g. a noise-free
// measured direction): then the paper's feasible point is needed.
bool CclSearch::exact_linearisation_point(MatrixXd& Pk, MatrixXd& Qk, MatrixXd& Sk,
                                          MatrixXd& Rk) const {
  if (opt_.start != CclStart::kBestExact) return false;
  const JumpDesign* from = std::isfinite(best_trP_) ? &best_ : s4_ok_ ? &s4_ : nullptr;
  if (from == nullptr) return false;
  Pk = from->P / scale_;
  Sk = stein_sum(stein_, from->P) / scale_;  // eq. (19): S_P = sum_k p0^k Abar^k P Abar^k'
  const Eigen::LLT<MatrixXd> lp(Pk), ls(Sk);
  if (lp.info() == Eigen::Success && ls.info() == Eigen::Success) {
    Qk = lp.solve(MatrixXd::Identity(ext_.nb, ext_.nb));
    Rk = ls.solve(MatrixXd::Identity(ext_.nb, ext_.nb));
  }
  return !(Qk.size() == 0 || !Qk.allFinite() || !Rk.allFinite());
}

// CCL at gamma from a feasible point: true when gains with tr(P) <= gamma were found.
bool CclSearch::ccl(double gamma) {
  Built b = build(s_, gamma / scale_);
  lmi::Solution sol;
  MatrixXd Pk, Qk, Sk, Rk;
  if (!exact_linearisation_point(Pk, Qk, Sk, Rk)) {
    sol = solve(b);  // step 2: a feasible point (no objective)
    if (!sol.ok()) {
      if (sol.status != lmi::Status::kInfeasible && fail_status_.empty())
        fail_status_ = lmi::to_string(sol.status);
      return false;
    }
    if (const double tr = consider(b, sol); std::isfinite(tr) && tr <= gamma) return true;
    Pk = sol.value(b.P), Qk = sol.value(b.Q), Sk = sol.value(b.S), Rk = sol.value(b.R);
  }
  int idle = 0;
  for (int k = 0; k < opt_.max_ccl_iterations; ++k) {
    if (k > 0) Pk = sol.value(b.P), Qk = sol.value(b.Q), Sk = sol.value(b.S), Rk = sol.value(b.R);
    // Step 3: the linearised objective at (Pk, Qk, Sk, Rk).
    b.prob.minimize(lmi::trace(Pk * lmi::Expr(b.Q)) + lmi::trace(Qk * b.P) +
                    lmi::trace(Sk * lmi::Expr(b.R)) + lmi::trace(Rk * lmi::Expr(b.S)));
    sol = solve(b);
    ++info_.ccl_iterations;
    if (!sol.ok()) {
      if (fail_status_.empty()) fail_status_ = lmi::to_string(sol.status);
      return false;
    }
    const double before = best_trP_;
    if (const double tr = consider(b, sol); std::isfinite(tr) && tr <= gamma * (1.0 + 1e-12))
      return true;
    // Stalled: the best exact tr(P) did not move for `patience` iterations (k_max of step 4
    // bounds the loop in any case).
    // Until some iterate has stable gains, only k_max ends the loop.
    const bool moved =
        !std::isfinite(best_trP_) || best_trP_ < before * (1.0 - opt_.stall_tolerance);
    idle = moved ? 0 : idle + 1;
    if (idle >= opt_.patience) return false;
  }
  return false;
}

// The first gains without the S4 linearisation: from the relaxation (Q, R free: min tr(P), a
// certified lower bound, then `lower`) or the paper's feasible point. False when the SDP failed.
bool CclSearch::first_gains(Built& first, double& lower) {
  const bool relax = !s4_ok_;
  if (relax) first.prob.minimize(lmi::trace(first.P));
  const lmi::Solution sol = solve(first);
  if (!sol.ok()) {
    failed_.status = lmi::to_string(sol.status);
    info_.lmi_status = failed_.status;
    return false;
  }
  if (relax) {
    lower = std::max(0.0, sol.objective * scale_);
    info_.relaxation_bound = lower;
  }
  consider(first, sol);
  return true;
}

// Bisection (section 4, steps 1-5) from [lower, best tr(P)].
void CclSearch::bisect(double lower) {
  double upper = best_trP_;
  int fruitless = 0;  // consecutive steps that found nothing better
  for (; info_.bisections < opt_.max_bisections && upper - lower >= opt_.relative_gap * upper;
       ++info_.bisections) {
    if (s4_ok_ && opt_.max_fruitless_steps > 0 && fruitless >= opt_.max_fruitless_steps) {
      info_.stopped_fruitless = true;
      info_.stop = "no_improvement";
      break;
    }
    const double gamma = 0.5 * (lower + upper);
    const double before = best_trP_;
    if (!ccl(gamma)) lower = gamma;
    fruitless = best_trP_ < before * (1.0 - opt_.stall_tolerance) ? 0 : fruitless + 1;
    upper = std::min(upper, best_trP_);  // the best exact fixed point so far bounds the optimum
    if (opt_.verbose)
      std::fprintf(stderr, "gamma %.6g -> [%.6g, %.6g] best %.6g\n", gamma, lower, upper,
                   best_trP_);
  }
  if (info_.stop.empty())
    info_.stop = upper - lower < opt_.relative_gap * upper ? "gap" : "max_bisections";
  info_.lower_bound = lower;
  info_.upper_bound = best_trP_;
}

JumpDesign CclSearch::run() {
  // The exact S4 design (value iteration). Every grouping's feasible set lies in
  // S4's (S1-S3 only add equalities): its tr(P) is a certified lower bound for the bisection,
  // far tighter than the LMI relaxation's (the paper starts at 0), and its (P, S_P) is where
  // the first CCL iterate is linearised.
  if (opt_.s4_bound) {
    s4_ = design_jump_iterative(ext_, prob_, Nbar_, Grouping::kS4);
    s4_ok_ = s4_.stable && s4_.status == "ok";
  }
  double lower = 0.0;
  if (s4_ok_) {
    info_.s4_bound = s4_.P.trace();
    lower = info_.s4_bound * (1.0 - 1e-9);
  }
  // The first gains: from CCL linearised at the S4 optimum (below), or, without it, from the
  // relaxation or the paper's feasible point (first_gains).
  Built first = build(s_, std::numeric_limits<double>::infinity());
  info_.size =
      build(s_, 1.0).prob.size();  // a bisection step's SDP (with its tr(P) <= gamma block)
  if (!s4_ok_ || opt_.start != CclStart::kBestExact) {
    if (!first_gains(first, lower)) return failed_;
  }
  if (!std::isfinite(best_trP_)) ccl(std::numeric_limits<double>::infinity());
  if (!std::isfinite(best_trP_)) {
    failed_.status = fail_status_.empty() ? "no_feasible_gains" : fail_status_;
    info_.lmi_status = fail_status_.empty() ? "optimal" : fail_status_;
    info_.lower_bound = lower;
    return failed_;
  }
  bisect(lower);
  return best_;
}

}  // namespace

JumpDesign design_jump_ccl(const ExtendedModel& ext, const std::vector<double>& prob, int Nbar,
                           Grouping grouping, const CclOptions& opt, CclInfo* info_out) {
  const Eigen::Index nb = ext.nb, nm = ext.nmb;
  const int per_N = groups_per_N(grouping, ext);
  // Checks shared with the evaluation (p0 >= 1, p0 rho^2 >= 1): a zero-gain evaluation.
  const std::vector<MatrixXd> zero(static_cast<std::size_t>(per_N) * Nbar, MatrixXd::Zero(nb, nm));
  JumpDesign failed = evaluate_jump_gains(ext, prob, Nbar, grouping, zero);
  failed.stable = false;
  if (failed.status.rfind("unstable:", 0) == 0 || failed.status == "no_measurements") {
    if (info_out) *info_out = CclInfo{};
    return failed;
  }
  failed.P.setConstant(std::nan(""));
  failed.Pt.setConstant(std::nan(""));

  const double scale = noise_scale(ext, opt);
  ExtendedModel sext = ext;
  sext.Q /= scale;
  sext.V /= scale;
  HistoryTerms h = history_terms(sext, prob[0], Nbar);  // noise terms on the normalised model
  const Setup s = make_setup(ext, sext, prob, Nbar, grouping, h, opt.group_moments);
  CclSearch search(ext, prob, Nbar, grouping, opt, scale, s, h.stein, failed);
  JumpDesign d = search.run();
  if (info_out) *info_out = search.info();
  return d;
}

}  // namespace ncosim::est
