// estimators/design/jump_design.cc — value iteration for the jump observer gains.
#include "estimators/design/jump_design.h"

#include <fmt/format.h>

#include <bit>
#include <cmath>
#include <limits>

namespace ncosim::est {

int groups_per_N(Grouping g, const ExtendedModel& ext) {
  switch (g) {
    case Grouping::kS1:
      return 1;
    case Grouping::kS2:
      return ext.sensors;
    case Grouping::kS3:
      return ext.fictitious_count();
    case Grouping::kS4:
      return (1 << ext.fictitious_count()) - 1;
  }
  return 0;
}

int group_of(Grouping g, const ExtendedModel& ext, std::uint64_t pattern) {
  switch (g) {
    case Grouping::kS1:
      return 0;
    case Grouping::kS2:
      return ext.real_sensors(pattern) - 1;
    case Grouping::kS3:
      return std::popcount(pattern) - 1;
    case Grouping::kS4:
      return static_cast<int>(pattern) - 1;
  }
  return 0;
}

namespace {

// Closed-form S4 gain of one term: L = X Cs'(Cs X Cs' + Vs)^-1 on the delivered rows.
Eigen::MatrixXd optimal_gain(const ExtendedModel& ext, const Eigen::MatrixXd& X,
                             const Eigen::VectorXd& mask) {
  Eigen::MatrixXd CX = mask.asDiagonal() * ext.C * X;  // rows outside the pattern zero
  Eigen::MatrixXd S = CX * ext.C.transpose() * mask.asDiagonal();
  S += mask.asDiagonal() * ext.V * mask.asDiagonal();
  for (Eigen::Index r = 0; r < S.rows(); ++r) {
    if (mask(r) == 0.0) S(r, r) = 1.0;  // decouple unused rows
  }
  return S.ldlt().solve(CX).transpose();
}

// Eq. (28) of Dolz et al. (2014) as printed (see JumpDesign::Pt_paper_eq28_erroneous).
Eigen::MatrixXd paper_eq28_erroneous(const ExtendedModel& ext, double p0,
                                     const Eigen::MatrixXd& stein, const Eigen::MatrixXd& P) {
  const Eigen::MatrixXd Sc = ext.A * P * ext.A.transpose() + ext.Q / (1.0 - p0);
  Eigen::MatrixXd Pt = (1.0 - p0) * P + p0 * stein_sum(stein, Sc);
  return 0.5 * (Pt + Pt.transpose());
}

struct Term {
  int N;  // 1..Nbar (Nbar = the tail N >= Nbar)
  std::uint64_t pattern;
  double weight;         // sum over the terms of one N is 1 for the tail, p0^(N-1)(1-p0) else
  Eigen::VectorXd mask;  // row mask of the pattern
  int group;             // global gain index
};

}  // namespace

HistoryTerms history_terms(const ExtendedModel& ext, double p0, int Nbar) {
  const Eigen::Index nb = ext.nb;
  HistoryTerms h;
  h.Apow.resize(Nbar + 1);
  h.SW.resize(Nbar + 1);
  h.Apow[0] = Eigen::MatrixXd::Identity(nb, nb);
  h.SW[0] = Eigen::MatrixXd::Zero(nb, nb);
  for (int N = 1; N <= Nbar; ++N) {
    h.Apow[N] = ext.A * h.Apow[N - 1];
    h.SW[N] = h.SW[N - 1] + h.Apow[N - 1] * ext.Q * h.Apow[N - 1].transpose();
  }
  h.stein = stein_operator(ext.A, p0);
  h.SWinf = stein_sum(h.stein, ext.Q);  // S'_W,inf (eq. 23)
  const Eigen::MatrixXd& AN = h.Apow[Nbar];
  h.tail_noise = h.SW[Nbar] + p0 * AN * h.SWinf * AN.transpose();
  return h;
}

double history_weight(double p0, int N, int Nbar) {
  return N < Nbar ? std::pow(p0, N - 1) : std::pow(p0, Nbar - 1) / (1.0 - p0);
}

std::string design_precheck(const ExtendedModel& ext, double p0) {
  if (p0 >= 1.0) return "no_measurements";
  const double rho = ext.A.eigenvalues().cwiseAbs().maxCoeff();
  if (p0 * rho * rho >= 1.0)
    return fmt::format("unstable: p0 rho(A)^2 = {:.4g} >= 1", p0 * rho * rho);
  return "";
}

namespace {

// The parts of a design that do not depend on its gains: the grouping, p0, which gain each
// (N, pattern) uses, and the patterns' row masks.
JumpDesign design_frame(const ExtendedModel& ext, const std::vector<double>& prob, int Nbar,
                        Grouping grouping) {
  JumpDesign d;
  d.grouping = grouping;
  d.Nbar = Nbar;
  const std::size_t patterns = prob.size();
  d.p0 = prob[0];
  const int per_N = groups_per_N(grouping, ext);
  d.stored_gains = static_cast<long>(per_N) * Nbar;
  d.gain_of.assign(Nbar, std::vector<int>(patterns, -1));
  for (int N = 1; N <= Nbar; ++N) {
    for (std::size_t m = 1; m < patterns; ++m) {
      d.gain_of[N - 1][m] = (N - 1) * per_N + group_of(grouping, ext, m);
    }
  }
  for (std::size_t m = 0; m < patterns; ++m) d.masks.push_back(ext.row_mask(m));
  return d;
}

// Pt at the fixed point P (corrected eq. 28; the printed one kept beside it): the design is done.
void finish_design(JumpDesign& d, const ExtendedModel& ext, const HistoryTerms& h) {
  const double p0 = d.p0;
  const Eigen::MatrixXd SP = stein_sum(h.stein, d.P);
  d.Pt = (1.0 - p0) * d.P + p0 * ((1.0 - p0) * ext.A * SP * ext.A.transpose() + h.SWinf);
  d.Pt = 0.5 * (d.Pt + d.Pt.transpose());
  d.Pt_paper_eq28_erroneous = paper_eq28_erroneous(ext, p0, h.stein, d.P);
  d.stable = true;
}

// The terms of (18) of positive weight: per N and pattern of positive probability.
std::vector<Term> weighted_terms(const JumpDesign& d, const std::vector<double>& prob) {
  std::vector<Term> terms;
  for (int N = 1; N <= d.Nbar; ++N) {
    const double wN = history_weight(d.p0, N, d.Nbar);
    for (std::size_t m = 1; m < prob.size(); ++m) {
      if (prob[m] <= 0.0) continue;
      terms.push_back({N, m, wN * prob[m], d.masks[m], d.gain_of[N - 1][m]});
    }
  }
  return terms;
}

// Patterns the design model gives probability 0 (e.g. a buffered sample seen alone) may still
// occur: the terms, of equal weights, of the groups no weighted term uses.
std::vector<Term> unweighted_terms(const JumpDesign& d, const std::vector<Term>& terms,
                                   std::size_t patterns) {
  std::vector<bool> weighted(d.gains.size(), false);
  for (const Term& t : terms) weighted[static_cast<std::size_t>(t.group)] = true;
  std::vector<Term> unweighted;
  for (int N = 1; N <= d.Nbar; ++N) {
    for (std::size_t m = 1; m < patterns; ++m) {
      const int g = d.gain_of[N - 1][m];
      if (!weighted[static_cast<std::size_t>(g)]) unweighted.push_back({N, m, 1.0, d.masks[m], g});
    }
  }
  return unweighted;
}

// One step of value iteration on (18): the prior covariances at P, the gains at those priors and
// the covariance they give.
class ValueIteration {
 public:
  ValueIteration(const ExtendedModel& ext, const HistoryTerms& h, JumpDesign& d)
      : ext_(ext),
        h_(h),
        d_(d),
        X_(d.Nbar + 1),
        num_(d.gains.size()),
        den_(d.gains.size()),
        I_(Eigen::MatrixXd::Identity(ext.nb, ext.nb)) {}

  // Prior covariance before an update N periods after the last one (tail: N >= Nbar,
  // conditional mixture).
  void priors(const Eigen::MatrixXd& P) {
    const int Nbar = d_.Nbar;
    const Eigen::MatrixXd& AN = h_.Apow[Nbar];
    for (int N = 1; N < Nbar; ++N) X_[N] = h_.Apow[N] * P * h_.Apow[N].transpose() + h_.SW[N];
    X_[Nbar] = (1.0 - d_.p0) * AN * stein_sum(h_.stein, P) * AN.transpose() + h_.tail_noise;
  }

  // Gains of the groups present in `ts` at the current priors: the closed form per term (S4) or
  // the weighted trace-minimising shared gain (S1-S3).
  void update_gains(const std::vector<Term>& ts) {
    if (d_.grouping == Grouping::kS4) {
      for (const Term& t : ts) d_.gains[t.group] = optimal_gain(ext_, X_[t.N], t.mask);
      return;
    }
    for (const Term& t : ts) {
      num_[t.group].setZero(ext_.nb, ext_.nmb);
      den_[t.group].setZero(ext_.nmb, ext_.nmb);
    }
    for (const Term& t : ts) {
      num_[t.group] += t.weight * X_[t.N] * ext_.C.transpose() * t.mask.asDiagonal();
      den_[t.group] += t.weight * t.mask.asDiagonal() *
                       (ext_.C * X_[t.N] * ext_.C.transpose() + ext_.V) * t.mask.asDiagonal();
    }
    for (const Term& t : ts) {
      if (den_[t.group].isZero(0.0)) continue;
      d_.gains[t.group] =
          num_[t.group] * den_[t.group].completeOrthogonalDecomposition().pseudoInverse();
    }
  }

  // Pnew = sum_t w_t (F X_N F' + L E V E' L'), F = I - L E C: the operator (18), symmetrised.
  void covariance(const std::vector<Term>& terms, Eigen::MatrixXd& Pnew) const {
    Pnew.setZero();
    for (const Term& t : terms) {
      const Eigen::MatrixXd LE = d_.gains[t.group] * t.mask.asDiagonal();
      const Eigen::MatrixXd F = I_ - LE * ext_.C;
      Pnew += t.weight * (F * X_[t.N] * F.transpose() + LE * ext_.V * LE.transpose());
    }
    Pnew = 0.5 * (Pnew + Pnew.transpose());
  }

 private:
  const ExtendedModel& ext_;
  const HistoryTerms& h_;
  JumpDesign& d_;
  std::vector<Eigen::MatrixXd> X_;
  std::vector<Eigen::MatrixXd> num_, den_;
  const Eigen::MatrixXd I_;
};

// Stall detection: a badly scaled model (an entry of 1e6 beside entries of 1e-2) reaches a
// floor of rounding noise far above the tolerance (relative change ~1e-8, not decreasing), and
// would go on to max_iterations (seconds per design). Windows of kStallWindow iterations: when
// a window's smallest relative change is below kStallBelow and not below kStallRatio times the
// previous window's, the iteration has stopped converging (at iteration 4000 at the earliest).
// A converging iteration (change ~ k^j r^k) passes every window while its change falls by 10 %
// per window, e.g. r < 0.99994 at j = 0: slower ones need more than max_iterations anyway.
// Changes above kStallBelow (a cycling or slowly converging iteration far from its fixed point)
// go on to max_iterations as before.
class StallWatch {
 public:
  // True when iteration `iteration`, of relative change `change`, ends a stalled window.
  bool stalled(int iteration, double change) {
    best_window_ = std::min(best_window_, change);
    if (iteration % kStallWindow != 0) return false;
    if (best_window_ < kStallBelow && best_window_ >= kStallRatio * best_before_) return true;
    best_before_ = best_window_;
    best_window_ = std::numeric_limits<double>::infinity();
    return false;
  }
  double smallest_change() const { return best_window_; }

 private:
  static constexpr int kStallWindow = 2000;
  static constexpr double kStallRatio = 0.9;
  static constexpr double kStallBelow = 1e-6;
  double best_before_ = std::numeric_limits<double>::infinity();  // the previous window's smallest
  double best_window_ = std::numeric_limits<double>::infinity();
};

}  // namespace

JumpDesign design_jump_iterative(const ExtendedModel& ext, const std::vector<double>& prob,
                                 int Nbar, Grouping grouping, int max_iterations,
                                 double tolerance) {
  JumpDesign d = design_frame(ext, prob, Nbar, grouping);
  const Eigen::Index nb = ext.nb;
  d.gains.assign(static_cast<std::size_t>(d.stored_gains), Eigen::MatrixXd::Zero(nb, ext.nmb));
  d.P = Eigen::MatrixXd::Zero(nb, nb);
  d.Pt = Eigen::MatrixXd::Constant(nb, nb, std::nan(""));
  if (std::string why = design_precheck(ext, d.p0); !why.empty()) {
    d.status = std::move(why);
    return d;
  }
  const HistoryTerms h = history_terms(ext, d.p0, Nbar);
  const std::vector<Term> terms = weighted_terms(d, prob);
  ValueIteration step(ext, h, d);
  Eigen::MatrixXd Pnew(nb, nb);
  StallWatch watch;
  for (d.iterations = 1; d.iterations <= max_iterations; ++d.iterations) {
    step.priors(d.P);
    step.update_gains(terms);
    step.covariance(terms, Pnew);
    if (!Pnew.allFinite() || Pnew.trace() > 1e15) {
      d.status = "diverged";
      return d;
    }
    const double change = (Pnew - d.P).cwiseAbs().maxCoeff();
    d.P = Pnew;
    const double scale = std::max(1.0, d.P.cwiseAbs().maxCoeff());
    if (change <= tolerance * scale) break;
    if (watch.stalled(d.iterations, change / scale)) {
      d.status = "not_converged";
      d.iteration_message = fmt::format(
          "stopped after {} iterations: the relative change stalled at {:.1e} (tolerance {:g}), "
          "rounding noise "
          "of a badly scaled model; rescale the plant and sensor matrices",
          d.iterations, watch.smallest_change(), tolerance);
      return d;
    }
  }
  if (d.iterations > max_iterations) {
    d.iterations = max_iterations;
    d.status = "not_converged";
    return d;
  }
  // Groups of probability-0 patterns: the gain of the same formula at the fixed point.
  if (const std::vector<Term> unweighted = unweighted_terms(d, terms, prob.size());
      !unweighted.empty()) {
    step.priors(d.P);
    step.update_gains(unweighted);
  }
  finish_design(d, ext, h);
  return d;
}

namespace {

Eigen::MatrixXd kron(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  Eigen::MatrixXd k(a.rows() * b.rows(), a.cols() * b.cols());
  for (Eigen::Index i = 0; i < a.rows(); ++i)
    for (Eigen::Index j = 0; j < a.cols(); ++j)
      k.block(i * b.rows(), j * b.cols(), b.rows(), b.cols()) = a(i, j) * b;
  return k;
}

// The operator (18) with fixed gains as vec(P) = T vec(P) + vec(U): T = sum w (F A^N (x) F A^N),
// the tail through the Stein sum.
struct LinearOperator {
  Eigen::MatrixXd T, U;
};
LinearOperator gains_operator(const JumpDesign& d, const ExtendedModel& ext,
                              const std::vector<double>& prob, const HistoryTerms& h) {
  const Eigen::Index nb = ext.nb, n2 = nb * nb;
  const int Nbar = d.Nbar;
  const double p0 = d.p0;
  LinearOperator op{Eigen::MatrixXd::Zero(n2, n2), Eigen::MatrixXd::Zero(nb, nb)};
  const Eigen::MatrixXd I = Eigen::MatrixXd::Identity(nb, nb);
  Eigen::MatrixXd tailT = Eigen::MatrixXd::Zero(n2, n2);
  for (int N = 1; N <= Nbar; ++N) {
    const double wN = history_weight(p0, N, Nbar);
    for (std::size_t m = 1; m < prob.size(); ++m) {
      if (prob[m] <= 0.0) continue;
      const double w = wN * prob[m];
      const Eigen::MatrixXd LE = d.gains[d.gain_of[N - 1][m]] * d.masks[m].asDiagonal();
      const Eigen::MatrixXd F = I - LE * ext.C;
      if (N < Nbar) {
        const Eigen::MatrixXd FA = F * h.Apow[N];
        op.T += w * kron(FA, FA);
        op.U += w * (F * h.SW[N] * F.transpose() + LE * ext.V * LE.transpose());
      } else {
        const Eigen::MatrixXd FA = F * h.Apow[Nbar];
        tailT += w * (1.0 - p0) * kron(FA, FA);
        op.U += w * (F * h.tail_noise * F.transpose() + LE * ext.V * LE.transpose());
      }
    }
  }
  op.T += tailT * h.stein;  // vec(S_P) = stein vec(P)
  return op;
}

// Groups without a weighted term: the fallback of design_jump_iterative, at d.P.
void fallback_gains(JumpDesign& d, const ExtendedModel& ext, const std::vector<double>& prob,
                    const HistoryTerms& h) {
  const Eigen::Index nb = ext.nb;
  const int Nbar = d.Nbar;
  const double p0 = d.p0;
  const std::size_t patterns = prob.size();
  const int per_N = groups_per_N(d.grouping, ext);
  const Eigen::MatrixXd& AN = h.Apow[Nbar];
  std::vector<bool> weighted(d.gains.size(), false);
  for (int N = 1; N <= Nbar; ++N)
    for (std::size_t m = 1; m < patterns; ++m)
      if (prob[m] > 0.0) weighted[static_cast<std::size_t>(d.gain_of[N - 1][m])] = true;
  for (std::size_t g = 0; g < d.gains.size(); ++g) {
    if (weighted[g]) continue;
    const int N = static_cast<int>(g) / per_N + 1;
    const Eigen::MatrixXd X =
        N < Nbar ? Eigen::MatrixXd(h.Apow[N] * d.P * h.Apow[N].transpose() + h.SW[N])
                 : Eigen::MatrixXd((1.0 - p0) * AN * stein_sum(h.stein, d.P) * AN.transpose() +
                                   h.tail_noise);
    Eigen::MatrixXd num = Eigen::MatrixXd::Zero(nb, ext.nmb),
                    den = Eigen::MatrixXd::Zero(ext.nmb, ext.nmb);
    for (std::size_t m = 1; m < patterns; ++m) {
      if (d.gain_of[N - 1][m] != static_cast<int>(g)) continue;
      num += X * ext.C.transpose() * d.masks[m].asDiagonal();
      den += d.masks[m].asDiagonal() * (ext.C * X * ext.C.transpose() + ext.V) *
             d.masks[m].asDiagonal();
    }
    if (!den.isZero(0.0)) d.gains[g] = num * den.completeOrthogonalDecomposition().pseudoInverse();
  }
}

}  // namespace

JumpDesign evaluate_jump_gains(const ExtendedModel& ext, const std::vector<double>& prob, int Nbar,
                               Grouping grouping, const std::vector<Eigen::MatrixXd>& gains) {
  JumpDesign d = design_frame(ext, prob, Nbar, grouping);
  const Eigen::Index nb = ext.nb;
  d.gains = gains;
  d.P = Eigen::MatrixXd::Constant(nb, nb, std::nan(""));
  d.Pt = d.P;
  if (gains.size() != static_cast<std::size_t>(d.stored_gains)) {
    d.status = "wrong_gain_count";
    return d;
  }
  if (std::string why = design_precheck(ext, d.p0); !why.empty()) {
    d.status = std::move(why);
    return d;
  }
  const HistoryTerms h = history_terms(ext, d.p0, Nbar);
  const LinearOperator op = gains_operator(d, ext, prob, h);
  const double radius = op.T.eigenvalues().cwiseAbs().maxCoeff();
  if (!std::isfinite(radius) || radius >= 1.0) {
    d.status = "unstable_gains";
    return d;
  }
  const Eigen::Index n2 = nb * nb;
  Eigen::VectorXd vecU = Eigen::Map<const Eigen::VectorXd>(op.U.data(), n2);
  Eigen::VectorXd vecP = (Eigen::MatrixXd::Identity(n2, n2) - op.T).partialPivLu().solve(vecU);
  d.P = Eigen::Map<const Eigen::MatrixXd>(vecP.data(), nb, nb);
  d.P = 0.5 * (d.P + d.P.transpose());
  fallback_gains(d, ext, prob, h);
  finish_design(d, ext, h);
  d.status = "ok";
  return d;
}

}  // namespace ncosim::est
