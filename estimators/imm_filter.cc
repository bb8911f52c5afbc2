// estimators/imm_filter.cc — IMM mixing, mode-matched Kalman filters, mode probabilities.
#include "estimators/imm_filter.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#include "kernel/check.h"

namespace ncosim::est {

namespace {

// Makes P exactly symmetric (averages the two triangles) without a temporary.
void symmetrize(Eigen::MatrixXd& P) {
  for (Eigen::Index c = 0; c < P.cols(); ++c) {
    for (Eigen::Index r = c + 1; r < P.rows(); ++r) {
      const double v = 0.5 * (P(r, c) + P(c, r));
      P(r, c) = v;
      P(c, r) = v;
    }
  }
}

// Below this size, coefficient-based (lazy) products beat Eigen's blocked GEMM, whose set-up
// dominates for the 2..16-state models of the mode estimators.
constexpr Eigen::Index kLazyMax = 16;

template <class D, class A, class B>
void mul(D&& dst, const A& a, const B& b, bool lazy) {
  if (lazy) {
    dst.noalias() = a.lazyProduct(b);
  } else {
    dst.noalias() = a * b;
  }
}
template <class D, class A, class B>
void mul_add(D&& dst, const A& a, const B& b, bool lazy) {
  if (lazy) {
    dst.noalias() += a.lazyProduct(b);
  } else {
    dst.noalias() += a * b;
  }
}

bool is_distribution(const Eigen::Ref<const Eigen::VectorXd>& p) {
  return p.allFinite() && p.minCoeff() >= 0.0 && std::abs(p.sum() - 1.0) <= 1e-9;
}

}  // namespace

ImmFilter::ImmFilter(std::vector<ImmMode> modes, const Eigen::MatrixXd& transition,
                     const Eigen::VectorXd& x0, const Eigen::MatrixXd& P0,
                     const Eigen::VectorXd& mu0)
    : modes_(std::move(modes)), M_(transition) {
  NCOSIM_CHECK(!modes_.empty());
  const auto s = static_cast<Eigen::Index>(modes_.size());
  n_ = modes_[0].F.rows();
  m_ = modes_[0].H.rows();
  nu_ = modes_[0].B.cols();
  NCOSIM_CHECK(n_ > 0 && m_ > 0);
  for (const ImmMode& mode : modes_) {
    NCOSIM_CHECK(mode.F.rows() == n_ && mode.F.cols() == n_);
    NCOSIM_CHECK(mode.B.rows() == n_ && mode.B.cols() == nu_);
    NCOSIM_CHECK(mode.Q.rows() == n_ && mode.Q.cols() == n_);
    NCOSIM_CHECK(mode.H.rows() == m_ && mode.H.cols() == n_);
    NCOSIM_CHECK(mode.R.rows() == m_ && mode.R.cols() == m_);
  }
  NCOSIM_CHECK(M_.rows() == s && M_.cols() == s);
  for (Eigen::Index i = 0; i < s; ++i) NCOSIM_CHECK(is_distribution(M_.row(i).transpose()));

  const auto ss = modes_.size();
  x_.assign(ss, Eigen::VectorXd::Zero(n_));
  x_mix_ = x_;
  P_.assign(ss, Eigen::MatrixXd::Zero(n_, n_));
  P_mix_ = P_;
  ws_.assign(ss, kalman::Workspace(n_, m_));
  loglik_ = Eigen::VectorXd::Zero(s);
  cbar_ = Eigen::VectorXd::Zero(s);
  mu_ = Eigen::VectorXd::Zero(s);
  log_mu_ = Eigen::VectorXd::Zero(s);
  omega_ = Eigen::MatrixXd::Zero(s, s);
  x_comb_ = Eigen::VectorXd::Zero(n_);
  d_ = Eigen::VectorXd::Zero(n_);
  dw_ = Eigen::VectorXd::Zero(n_);
  P_comb_ = Eigen::MatrixXd::Zero(n_, n_);
  rows_.assign(static_cast<std::size_t>(m_), 0);
  reset(x0, P0, mu0);
}

void ImmFilter::reset(const Eigen::VectorXd& x0, const Eigen::MatrixXd& P0,
                      const Eigen::VectorXd& mu0) {
  NCOSIM_CHECK(x0.size() == n_ && P0.rows() == n_ && P0.cols() == n_);
  NCOSIM_CHECK(mu0.size() == static_cast<Eigen::Index>(modes_.size()) && is_distribution(mu0));
  for (std::size_t j = 0; j < modes_.size(); ++j) {
    x_[j] = x0;
    P_[j] = P0;
  }
  mu_ = mu0;
  cbar_ = mu0;
  loglik_.setZero();
  status_ = ImmStatus::kOk;
  last_applied_ = false;
  combine();
}

// Steps 1-2: mixing probabilities mu_{i|j} and the mixed initial condition of each filter.
void ImmFilter::mix() {
  const Eigen::Index s = mu_.size();
  cbar_.noalias() = M_.transpose() * mu_;
  for (Eigen::Index j = 0; j < s; ++j) {
    for (Eigen::Index i = 0; i < s; ++i) {
      // An unreachable mode (cbar_j = 0) keeps its own estimate; its probability stays 0.
      omega_(i, j) = cbar_(j) > 0.0 ? M_(i, j) * mu_(i) / cbar_(j) : (i == j ? 1.0 : 0.0);
    }
  }
  for (Eigen::Index j = 0; j < s; ++j) {
    auto& xm = x_mix_[static_cast<std::size_t>(j)];
    auto& Pm = P_mix_[static_cast<std::size_t>(j)];
    xm.setZero();
    for (Eigen::Index i = 0; i < s; ++i) xm += omega_(i, j) * x_[static_cast<std::size_t>(i)];
    Pm.setZero();
    // Pm += w (P_i + d d'), d = x_i - xm: one fused pass over the column-major storage (the
    // separate Eigen expressions cost more than the arithmetic at these sizes).
    const Eigen::Index n = n_;
    double* pm = Pm.data();
    double* d = d_.data();
    for (Eigen::Index i = 0; i < s; ++i) {
      const double w = omega_(i, j);
      if (w == 0.0) continue;
      const double* xi = x_[static_cast<std::size_t>(i)].data();
      const double* pi = P_[static_cast<std::size_t>(i)].data();
      for (Eigen::Index r = 0; r < n; ++r) d[r] = xi[r] - xm(r);
      for (Eigen::Index c = 0; c < n; ++c) {
        const double wdc = w * d[c];
        for (Eigen::Index r = 0; r < n; ++r) pm[c * n + r] += w * pi[c * n + r] + wdc * d[r];
      }
    }
  }
}

// Step 5 (also used for the prior): x = sum_j mu_j x_j, P = sum_j mu_j (P_j + spread).
void ImmFilter::combine() {
  const auto s = modes_.size();
  x_comb_.setZero();
  for (std::size_t j = 0; j < s; ++j) x_comb_ += mu_(static_cast<Eigen::Index>(j)) * x_[j];
  p_stale_ = true;
}

const Eigen::MatrixXd& ImmFilter::P() const {
  if (p_stale_) combine_covariance();
  return P_comb_;
}

void ImmFilter::combine_covariance() const {
  const auto s = modes_.size();
  P_comb_.setZero();
  for (std::size_t j = 0; j < s; ++j) {
    const double w = mu_(static_cast<Eigen::Index>(j));
    if (w == 0.0) continue;
    d_ = x_[j] - x_comb_;
    dw_ = w * d_;
    P_comb_ += w * P_[j];
    mul_add(P_comb_, dw_, d_.transpose(), n_ <= kLazyMax);
  }
  symmetrize(P_comb_);
  p_stale_ = false;
}

void ImmFilter::predict() {
  NCOSIM_CHECK(nu_ == 0);
  predict(Eigen::VectorXd());  // size 0: no allocation
}

// Step 3, first half: mode-matched prediction from the mixed initial conditions.
void ImmFilter::predict(const Eigen::Ref<const Eigen::VectorXd>& u) {
  NCOSIM_CHECK(u.size() == nu_);
  mix();
  for (std::size_t j = 0; j < modes_.size(); ++j) {
    const ImmMode& mode = modes_[j];
    const bool lazy = n_ <= kLazyMax;
    mul(x_[j], mode.F, x_mix_[j], lazy);
    if (nu_ > 0) mul_add(x_[j], mode.B, u, lazy);
    // P = F Pm F' + Q (the Kalman kernel: exactly symmetric).
    P_[j] = P_mix_[j];
    kalman::predict_covariance(mode.F, mode.Q, P_[j], ws_[j]);
  }
  mu_ = cbar_;
  combine();
}

void ImmFilter::update(const Eigen::Ref<const Eigen::VectorXd>& z) {
  NCOSIM_CHECK(z.size() == m_);
  for (Eigen::Index r = 0; r < m_; ++r) rows_[static_cast<std::size_t>(r)] = r;
  m_used_ = m_;
  correct(z);
}

void ImmFilter::update(const Eigen::Ref<const Eigen::VectorXd>& z,
                       const Eigen::Ref<const Eigen::VectorXd>& row_mask) {
  NCOSIM_CHECK(z.size() == m_ && row_mask.size() == m_);
  m_used_ = 0;
  for (Eigen::Index r = 0; r < m_; ++r) {
    if (row_mask(r) != 0.0) rows_[static_cast<std::size_t>(m_used_++)] = r;
  }
  if (m_used_ == 0) {
    skip_update();
    return;
  }
  correct(z);
}

void ImmFilter::skip_update() {
  loglik_.setZero();
  last_applied_ = false;
}

void ImmFilter::fail(ImmStatus why) {
  if (status_ == ImmStatus::kOk) status_ = why;
  loglik_.setZero();
  last_applied_ = false;
}

// Step 3, second half, and step 4. Pass 1 factors every mode's update (estimators/kalman_update.h:
// S_j = L_j L_j', w_j = L_j^-1 y_j, U_j = L_j^-1 H_j P_j in mode j's workspace); pass 2 applies
// them only if every mode succeeded, so a failure leaves all priors untouched.
void ImmFilter::correct(const Eigen::Ref<const Eigen::VectorXd>& z) {
  const Eigen::Index mr = m_used_;  // rows used
  for (std::size_t j = 0; j < modes_.size(); ++j) {
    const ImmMode& mode = modes_[j];
    kalman::Workspace& ws = ws_[j];
    for (Eigen::Index a = 0; a < mr; ++a) {
      const Eigen::Index ra = rows_[static_cast<std::size_t>(a)];
      ws.C.row(a) = mode.H.row(ra);
      ws.y(a) = z(ra);
      for (Eigen::Index b = 0; b < mr; ++b)
        ws.R(a, b) = mode.R(ra, rows_[static_cast<std::size_t>(b)]);
    }
    ws.m = mr;
    switch (kalman::factor(x_[j], P_[j], ws)) {
      case kalman::Factor::kOk:
        break;
      case kalman::Factor::kNotPositiveDefinite:
        return fail(ImmStatus::kInnovationNotPositiveDefinite);
      case kalman::Factor::kNonFinite:
        return fail(ImmStatus::kNonFiniteLikelihood);
    }
    loglik_(static_cast<Eigen::Index>(j)) = ws.log_likelihood();
    if (std::isnan(loglik_(static_cast<Eigen::Index>(j))) || !ws.U.topRows(mr).allFinite()) {
      return fail(ImmStatus::kNonFiniteLikelihood);
    }
  }
  // Step 4 in the log domain: mu_j ∝ exp(log mu_j + log Lambda_j - max).
  const Eigen::Index s = mu_.size();
  double amax = -std::numeric_limits<double>::infinity();
  for (Eigen::Index j = 0; j < s; ++j) {
    log_mu_(j) = std::log(mu_(j)) + loglik_(j);
    amax = std::max(amax, log_mu_(j));
  }
  if (!std::isfinite(amax)) return fail(ImmStatus::kNonFiniteLikelihood);
  double sum = 0.0;
  for (Eigen::Index j = 0; j < s; ++j) {
    mu_(j) = std::exp(log_mu_(j) - amax);
    sum += mu_(j);
  }
  mu_ /= sum;  // sum >= 1: the maximising term is exp(0)
  for (std::size_t j = 0; j < modes_.size(); ++j) kalman::apply(x_[j], P_[j], ws_[j]);
  last_applied_ = true;
  combine();
}

double ImmFilter::likelihood(int j) const { return std::exp(loglik_(j)); }

int ImmFilter::most_probable_mode() const {
  Eigen::Index best = 0;
  mu_.maxCoeff(&best);
  return static_cast<int>(best);
}

}  // namespace ncosim::est
