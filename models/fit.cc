// models/fit.cc — the machinery of the maximum-likelihood fits (models/fit.h): the HMM
// likelihood, Baum–Welch from several starts, Wald intervals and goodness of fit. The families
// themselves are declared entries in models/fit_families.cc.
#include "models/fit.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <stdexcept>

#include "models/fit_internal.h"
#include "models/link.h"
#include "models/plant.h"  // stationary_law

namespace ncosim::models {

namespace fit_detail {

constexpr double kTiny = 1e-300;

int alphabet(const std::vector<int>& sym) {
  int m = 0;
  for (const int s : sym) m = std::max(m, s);
  return m + 1;
}

// The log of a product of many factors in [kTiny, 1]-ish: one log per block of factors instead
// of one per factor (the product is flushed into the sum before it could underflow).
class LogProduct {
 public:
  void add(double c) {
    if (c < 1e-20) {
      sum_ += std::log(c);
      return;
    }
    prod_ *= c;
    if (prod_ < 1e-280) {
      sum_ += std::log(prod_);
      prod_ = 1.0;
    }
  }
  double value() const { return sum_ + std::log(prod_); }

 private:
  double sum_ = 0.0, prod_ = 1.0;
};

// The two-state case of e_step (Gilbert–Elliott: every EM iteration of `ncosim fit`'s default
// family): the same recursions with the model in registers, the inverse scales stored so that
// the backward pass multiplies instead of dividing (bench/README.md, "ncosim fit").
double e_step2(const FateHmm& h, const std::vector<int>& sym, Eigen::MatrixXd* A,
               Eigen::MatrixXd* B, std::vector<double>& alpha, std::vector<double>& inv_scale) {
  const int M = static_cast<int>(h.emission.cols());
  const std::size_t N = sym.size();
  const Eigen::VectorXd pi = h.stationary();
  const double t00 = h.transition(0, 0), t01 = h.transition(0, 1), t10 = h.transition(1, 0),
               t11 = h.transition(1, 1);
  std::vector<double> E(static_cast<std::size_t>(2 * M));
  for (int m = 0; m < M; ++m) {
    E[static_cast<std::size_t>(2 * m)] = h.emission(0, m);
    E[static_cast<std::size_t>(2 * m + 1)] = h.emission(1, m);
  }
  alpha.resize(2 * N);
  inv_scale.resize(N);
  LogProduct ll;
  double a0, a1;
  {
    const double* e = &E[static_cast<std::size_t>(2 * sym[0])];
    a0 = pi(0) * e[0];
    a1 = pi(1) * e[1];
    const double c = std::max(a0 + a1, kTiny);
    const double inv = 1.0 / c;
    a0 *= inv;
    a1 *= inv;
    alpha[0] = a0;
    alpha[1] = a1;
    inv_scale[0] = inv;
    ll.add(c);
  }
  // Normalised every 16 packets (and when small, and at the last packet) rather than at every
  // one: the division then leaves the loop's dependency chain. Any positive scales give the same
  // posteriors as long as the backward pass uses them too and the last step is normalised (then
  // their product is the likelihood).
  for (std::size_t t = 1; t < N; ++t) {
    const double* e = &E[static_cast<std::size_t>(2 * sym[t])];
    const double n0 = (a0 * t00 + a1 * t10) * e[0];
    const double n1 = (a0 * t01 + a1 * t11) * e[1];
    const double sum = n0 + n1;
    double inv = 1.0;
    if ((t & 15U) == 0 || sum < 1e-100 || t + 1 == N) {
      const double c = std::max(sum, kTiny);
      inv = 1.0 / c;
      ll.add(c);
    }
    a0 = n0 * inv;
    a1 = n1 * inv;
    alpha[2 * t] = a0;
    alpha[2 * t + 1] = a1;
    inv_scale[t] = inv;
  }
  if (A == nullptr) return ll.value();
  std::vector<double> b(static_cast<std::size_t>(2 * M), 0.0);
  double b0 = 1.0, b1 = 1.0, x00 = 0.0, x01 = 0.0, x10 = 0.0, x11 = 0.0;
  for (std::size_t t = N; t-- > 0;) {
    const double al0 = alpha[2 * t], al1 = alpha[2 * t + 1];
    double* bs = &b[static_cast<std::size_t>(2 * sym[t])];
    bs[0] += al0 * b0;
    bs[1] += al1 * b1;
    if (t == 0) break;
    // w_j = e_j(o_t) beta_t(j) / c_t; xi_{t-1}(i, j) = alpha_{t-1}(i) T_ij w_j.
    const double* e = &E[static_cast<std::size_t>(2 * sym[t])];
    const double w0 = e[0] * b0 * inv_scale[t], w1 = e[1] * b1 * inv_scale[t];
    const double p0 = alpha[2 * t - 2], p1 = alpha[2 * t - 1];
    const double u00 = t00 * w0, u01 = t01 * w1, u10 = t10 * w0, u11 = t11 * w1;
    x00 += p0 * u00;
    x01 += p0 * u01;
    x10 += p1 * u10;
    x11 += p1 * u11;
    b0 = u00 + u01;
    b1 = u10 + u11;
  }
  A->resize(2, 2);
  *A << x00, x01, x10, x11;
  B->resize(2, M);
  for (int m = 0; m < M; ++m) {
    (*B)(0, m) = b[static_cast<std::size_t>(2 * m)];
    (*B)(1, m) = b[static_cast<std::size_t>(2 * m + 1)];
  }
  return ll.value();
}

// Scaled forward-backward: accumulates expected transition counts A (K x K) and emission counts
// B (K x M); returns the log-likelihood. `alpha` and `scale` are work buffers.
double e_step(const FateHmm& h, const std::vector<int>& sym, Eigen::MatrixXd* A, Eigen::MatrixXd* B,
              std::vector<double>& alpha, std::vector<double>& scale) {
  const int K = static_cast<int>(h.transition.rows());
  if (K == 2) return e_step2(h, sym, A, B, alpha, scale);
  const int M = static_cast<int>(h.emission.cols());
  const std::size_t N = sym.size();
  const Eigen::VectorXd pi = h.stationary();
  // Row-major copies for the inner loops.
  std::vector<double> T(static_cast<std::size_t>(K * K)), E(static_cast<std::size_t>(M * K));
  for (int i = 0; i < K; ++i) {
    for (int j = 0; j < K; ++j) T[static_cast<std::size_t>(i * K + j)] = h.transition(i, j);
    for (int m = 0; m < M; ++m) E[static_cast<std::size_t>(m * K + i)] = h.emission(i, m);
  }
  alpha.resize(N * static_cast<std::size_t>(K));
  scale.resize(N);
  LogProduct ll;
  {
    const double* e = &E[static_cast<std::size_t>(sym[0] * K)];
    double c = 0.0;
    for (int j = 0; j < K; ++j) c += alpha[static_cast<std::size_t>(j)] = pi(j) * e[j];
    c = std::max(c, kTiny);
    for (int j = 0; j < K; ++j) alpha[static_cast<std::size_t>(j)] /= c;
    scale[0] = c;
    ll.add(c);
  }
  for (std::size_t t = 1; t < N; ++t) {
    const double* prev = &alpha[(t - 1) * static_cast<std::size_t>(K)];
    double* cur = &alpha[t * static_cast<std::size_t>(K)];
    const double* e = &E[static_cast<std::size_t>(sym[t] * K)];
    double c = 0.0;
    for (int j = 0; j < K; ++j) {
      double s = 0.0;
      for (int i = 0; i < K; ++i) s += prev[i] * T[static_cast<std::size_t>(i * K + j)];
      cur[j] = s * e[j];
      c += cur[j];
    }
    c = std::max(c, kTiny);
    const double inv = 1.0 / c;
    for (int j = 0; j < K; ++j) cur[j] *= inv;
    scale[t] = c;
    ll.add(c);
  }
  if (A == nullptr) return ll.value();
  A->setZero(K, K);
  B->setZero(K, M);
  std::vector<double> beta(static_cast<std::size_t>(K), 1.0), next(static_cast<std::size_t>(K)),
      w(static_cast<std::size_t>(K));
  std::vector<double> a(static_cast<std::size_t>(K * K), 0.0);
  for (std::size_t t = N; t-- > 0;) {
    const double* al = &alpha[t * static_cast<std::size_t>(K)];
    for (int i = 0; i < K; ++i) (*B)(i, sym[t]) += al[i] * beta[static_cast<std::size_t>(i)];
    if (t == 0) break;
    // w_j = e_j(o_t) beta_t(j) / c_t; xi_{t-1}(i, j) = alpha_{t-1}(i) T_ij w_j.
    const double* e = &E[static_cast<std::size_t>(sym[t] * K)];
    const double inv = 1.0 / scale[t];
    for (int j = 0; j < K; ++j)
      w[static_cast<std::size_t>(j)] = e[j] * beta[static_cast<std::size_t>(j)] * inv;
    const double* ap = &alpha[(t - 1) * static_cast<std::size_t>(K)];
    for (int i = 0; i < K; ++i) {
      double s = 0.0;
      for (int j = 0; j < K; ++j) {
        const double tw = T[static_cast<std::size_t>(i * K + j)] * w[static_cast<std::size_t>(j)];
        a[static_cast<std::size_t>(i * K + j)] += ap[i] * tw;
        s += tw;
      }
      next[static_cast<std::size_t>(i)] = s;
    }
    beta.swap(next);
  }
  for (int i = 0; i < K; ++i) {
    for (int j = 0; j < K; ++j) (*A)(i, j) = a[static_cast<std::size_t>(i * K + j)];
  }
  return ll.value();
}

void normalise_rows(Eigen::MatrixXd& m) {
  for (Eigen::Index i = 0; i < m.rows(); ++i) {
    const double s = m.row(i).sum();
    if (s > 0.0) {
      m.row(i) /= s;
    } else {
      m.row(i).setConstant(1.0 / static_cast<double>(m.cols()));
    }
  }
}

// One EM step: the log-likelihood of `h` and the updated model.
double em_map(const FateHmm& h, const std::vector<int>& sym, FateHmm& next,
              std::vector<double>& alpha, std::vector<double>& scale, Eigen::MatrixXd& A,
              Eigen::MatrixXd& B) {
  const double ll = e_step(h, sym, &A, &B, alpha, scale);
  normalise_rows(A);
  normalise_rows(B);
  next.transition = A;
  next.emission = B;
  return ll;
}

// Back to a valid model after an extrapolation: entries clipped to [0, 1], rows renormalised.
void project(FateHmm& h) {
  for (Eigen::MatrixXd* m : {&h.transition, &h.emission}) {
    *m = m->cwiseMax(0.0).cwiseMin(1.0);
    normalise_rows(*m);
  }
}

// Baum–Welch accelerated by SQUAREM (Varadhan & Roland 2008, scheme S3): from h0, two EM steps
// h1 = F(h0), h2 = F(h1), r = h1 - h0, v = h2 - 2 h1 + h0, alpha = -|r| / |v| (at most -1), the
// extrapolation h' = h0 - 2 alpha r + alpha^2 v (projected) is kept when its likelihood is not
// below LL(h1), else h2. Stops when one EM step gains less than `tol_total`. `iterations`
// counts E-steps (likelihood evaluations).
EmOutcome baum_welch(FateHmm h, const std::vector<int>& sym, int max_iter, double tol_total) {
  std::vector<double> alpha, scale;
  Eigen::MatrixXd A, B;
  EmOutcome out;
  FateHmm h1, h2, hp, h3;
  int evals = 0;
  while (evals < max_iter) {
    const double ll0 = em_map(h, sym, h1, alpha, scale, A, B);
    const double ll1 = em_map(h1, sym, h2, alpha, scale, A, B);
    evals += 2;
    out.hmm = h1;
    out.loglik = ll1;
    out.iterations = evals;
    if (ll1 - ll0 < tol_total) {
      out.converged = true;
      return out;
    }
    const Eigen::MatrixXd rt = h1.transition - h.transition, re = h1.emission - h.emission;
    const Eigen::MatrixXd vt = h2.transition - 2.0 * h1.transition + h.transition,
                          ve = h2.emission - 2.0 * h1.emission + h.emission;
    const double rr = rt.squaredNorm() + re.squaredNorm(), vv = vt.squaredNorm() + ve.squaredNorm();
    double a = vv > 0.0 ? -std::sqrt(rr / vv) : -1.0;
    if (!std::isfinite(a) || a > -1.0) a = -1.0;
    hp.transition = h.transition - 2.0 * a * rt + a * a * vt;
    hp.emission = h.emission - 2.0 * a * re + a * a * ve;
    project(hp);
    if (a == -1.0 || evals >= max_iter) {
      h = h2;
      continue;
    }
    const double llp = em_map(hp, sym, h3, alpha, scale, A, B);
    ++evals;
    h = std::isfinite(llp) && llp >= ll1 ? h3 : h2;
  }
  out.loglik = e_step(h, sym, nullptr, nullptr, alpha, scale);
  out.hmm = h;
  return out;
}

// Orders the hidden states by their loss probability (state 0: the best).
void sort_states(FateHmm& h) {
  const Eigen::Index K = h.transition.rows();
  std::vector<Eigen::Index> order(static_cast<std::size_t>(K));
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](Eigen::Index a, Eigen::Index b) {
    return h.emission(a, 0) < h.emission(b, 0);
  });
  FateHmm s = h;
  for (Eigen::Index i = 0; i < K; ++i) {
    s.emission.row(i) = h.emission.row(order[static_cast<std::size_t>(i)]);
    for (Eigen::Index j = 0; j < K; ++j) {
      s.transition(i, j) =
          h.transition(order[static_cast<std::size_t>(i)], order[static_cast<std::size_t>(j)]);
    }
  }
  h = s;
}

// Loss runs of the trace: runs[L - 1] = number of maximal runs of L losses.
std::vector<std::int64_t> loss_runs(const std::vector<int>& sym) {
  std::vector<std::int64_t> runs;
  std::int64_t open = 0;
  auto close = [&] {
    if (open == 0) return;
    if (static_cast<std::size_t>(open) > runs.size())
      runs.resize(static_cast<std::size_t>(open), 0);
    ++runs[static_cast<std::size_t>(open - 1)];
    open = 0;
  };
  for (const int s : sym) {
    if (s == 0) {
      ++open;
    } else {
      close();
    }
  }
  close();
  return runs;
}

std::vector<double> hmm_start_emission(int K, int M, const std::vector<double>& freq,
                                       double spread) {
  // State s: loss between P (1 - spread) and P + spread (1 - P), delays tilted towards short
  // (good) or long (bad) ones.
  const double P = freq[0];
  std::vector<double> out(static_cast<std::size_t>(K * M));
  for (int s = 0; s < K; ++s) {
    const double f = K == 1 ? 0.5 : static_cast<double>(s) / (K - 1);
    const double lo = P * (1.0 - spread), hi = P + spread * (1.0 - P);
    const double loss = std::clamp(lo + f * (hi - lo), 1e-4, 1.0 - 1e-4);
    double delivered = 0.0;
    std::vector<double> q(static_cast<std::size_t>(M), 0.0);
    for (int m = 1; m < M; ++m) {
      const double tilt = std::exp(spread * (2.0 * f - 1.0) * (m - 1) / std::max(1, M - 2));
      q[static_cast<std::size_t>(m)] = (freq[static_cast<std::size_t>(m)] + 1e-6) * tilt;
      delivered += q[static_cast<std::size_t>(m)];
    }
    out[static_cast<std::size_t>(s * M)] = loss;
    for (int m = 1; m < M; ++m) {
      out[static_cast<std::size_t>(s * M + m)] =
          delivered > 0.0 ? (1.0 - loss) * q[static_cast<std::size_t>(m)] / delivered : 0.0;
    }
  }
  return out;
}

// Baum–Welch from several starts: a short run of each, then the best one to convergence.
EmOutcome fit_hidden(int K, const std::vector<int>& sym, const FitOptions& o, int& starts_used,
                     double mean_burst) {
  const int M = alphabet(sym);
  std::vector<double> freq(static_cast<std::size_t>(std::max(M, 2)), 0.0);
  for (const int s : sym) freq[static_cast<std::size_t>(s)] += 1.0;
  for (double& f : freq) f /= static_cast<double>(sym.size());
  const int Mm = std::max(M, 2);
  std::vector<FateHmm> starts;
  const double stays[] = {0.95, 0.7, 0.99, 0.5, 0.9, 0.8};
  const double spreads[] = {0.9, 0.5, 0.99, 0.3, 0.7, 0.95};
  // A moment-matched start for two states: Gilbert's chain with the trace's loss and mean run.
  if (K == 2 && freq[0] > 0.0 && freq[0] < 1.0) {
    const GilbertElliottByMean g =
        gilbert_elliott_by_mean(freq[0], std::max(mean_burst, 1.0), 0.0, 1.0);
    if (g.error.empty() && g.p_good_to_bad > 0.0 && g.p_bad_to_good > 0.0) {
      FateHmm h;
      h.transition.resize(2, 2);
      h.transition << 1.0 - g.p_good_to_bad, g.p_good_to_bad, g.p_bad_to_good,
          1.0 - g.p_bad_to_good;
      const std::vector<double> e = hmm_start_emission(2, Mm, freq, 0.9);
      h.emission =
          Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(
              e.data(), 2, Mm);
      starts.push_back(h);
    }
  }
  for (int s = 0; static_cast<int>(starts.size()) < std::max(1, o.starts); ++s) {
    const double stay = stays[s % 6], spread = spreads[(s + s / 6) % 6];
    FateHmm h;
    h.transition = Eigen::MatrixXd::Constant(K, K, (1.0 - stay) / std::max(1, K - 1));
    h.transition.diagonal().setConstant(K == 1 ? 1.0 : stay);
    const std::vector<double> e = hmm_start_emission(K, Mm, freq, spread);
    h.emission =
        Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(
            e.data(), K, Mm);
    starts.push_back(h);
  }
  starts_used = static_cast<int>(starts.size());
  const double tol = o.tolerance * static_cast<double>(sym.size());
  EmOutcome best;
  best.loglik = -INFINITY;
  int burn_iterations = 0;
  for (const FateHmm& h : starts) {
    EmOutcome r = baum_welch(h, sym, std::min(o.max_iterations, 25), tol);
    burn_iterations += r.iterations;
    if (r.loglik > best.loglik) best = r;
  }
  if (!best.converged && best.iterations < o.max_iterations) {
    const int done = best.iterations;
    EmOutcome r = baum_welch(best.hmm, sym, o.max_iterations - done, tol);
    r.iterations += done;
    best = r;
  }
  (void)burn_iterations;
  sort_states(best.hmm);
  return best;
}

// The free coordinates of a model: in every row of `transition` and `emission`, the entries
// other than the largest (the largest is 1 - the others); zero entries stay fixed at 0.

Coordinates free_coordinates(const FateHmm& h) {
  Coordinates c;
  auto add = [&](const Eigen::MatrixXd& m, bool emission) {
    for (Eigen::Index i = 0; i < m.rows(); ++i) {
      Eigen::Index dep = 0;
      m.row(i).maxCoeff(&dep);
      for (Eigen::Index j = 0; j < m.cols(); ++j) {
        if (j != dep && m(i, j) > 1e-12) c.entries.push_back({emission, i, j, dep});
      }
    }
  };
  add(h.transition, false);
  add(h.emission, true);
  return c;
}

FateHmm moved(const FateHmm& h, const Coordinates& c, const Eigen::VectorXd& delta) {
  FateHmm m = h;
  for (std::size_t k = 0; k < c.entries.size(); ++k) {
    const auto& e = c.entries[k];
    Eigen::MatrixXd& mat = e.emission ? m.emission : m.transition;
    mat(e.row, e.col) += delta(static_cast<Eigen::Index>(k));
    mat(e.row, e.dependent) -= delta(static_cast<Eigen::Index>(k));
  }
  return m;
}

std::string num(double v) { return fmt::format("{:.12g}", v); }

std::string list(const std::vector<double>& v) {
  std::string s = "[";
  for (std::size_t i = 0; i < v.size(); ++i) s += (i ? ", " : "") + num(v[i]);
  return s + "]";
}

// A probability vector with its largest entry set to 1 - the others (exact sum to 1 in the
// scenario reader's tolerance after printing).
std::vector<double> law(std::vector<double> v) {
  double s = 0.0;
  for (const double x : v) s += x;
  for (double& x : v) x = s > 0.0 ? x / s : 0.0;
  return v;
}

void goodness_of_fit(FitResult& r, const std::vector<int>& sym, int lags) {
  const FateHmm& h = r.model;
  const Eigen::Index K = h.transition.rows();
  const Eigen::VectorXd l = h.emission.col(0);
  const Eigen::VectorXd d = Eigen::VectorXd::Ones(K) - l;
  const Eigen::VectorXd pi = h.stationary();
  // Observed.
  const std::vector<std::int64_t> runs = loss_runs(sym);
  std::int64_t total = 0;
  for (const auto n : runs) total += n;
  for (const auto n : runs)
    r.burst_observed.push_back(total > 0 ? static_cast<double>(n) / static_cast<double>(total)
                                         : 0.0);
  // Model: w = P(state at the first loss of a run), then P(run = L) = w (T L)^{L-1} T d.
  Eigen::RowVectorXd w = (pi.cwiseProduct(d)).transpose() * h.transition;
  w = w.cwiseProduct(l.transpose());
  const double norm = w.sum();
  double model_mass = 0.0;
  for (std::size_t L = 1; L <= runs.size(); ++L) {
    double p = 0.0;
    if (norm > 0.0) {
      p = (w * (h.transition * d))(0) / norm;
      w = (w * h.transition).cwiseProduct(l.transpose());
    }
    r.burst_model.push_back(p);
    model_mass += p;
  }
  r.burst_tv = 0.5 * std::max(0.0, 1.0 - model_mass);
  for (std::size_t i = 0; i < runs.size(); ++i)
    r.burst_tv += 0.5 * std::abs(r.burst_observed[i] - r.burst_model[i]);
  // Autocorrelation of the loss indicator.
  const auto N = static_cast<std::int64_t>(sym.size());
  double P = 0.0;
  for (const int s : sym) P += s == 0 ? 1.0 : 0.0;
  P /= static_cast<double>(N);
  const double Pm = pi.dot(l);
  if (!(P > 0.0 && P < 1.0) || !(Pm > 0.0 && Pm < 1.0)) return;
  Eigen::RowVectorXd v = pi.cwiseProduct(l).transpose();
  double ss = 0.0;
  int used = 0;
  for (int k = 1; k <= lags && k < N; ++k) {
    std::int64_t both = 0;
    for (std::int64_t t = 0; t + k < N; ++t)
      both += (sym[static_cast<std::size_t>(t)] == 0) & (sym[static_cast<std::size_t>(t + k)] == 0);
    const double obs =
        (static_cast<double>(both) / static_cast<double>(N - k) - P * P) / (P * (1.0 - P));
    v = v * h.transition;
    const double mod = (v.dot(l.transpose()) - Pm * Pm) / (Pm * (1.0 - Pm));
    r.acf_observed.push_back(obs);
    r.acf_model.push_back(mod);
    ss += (obs - mod) * (obs - mod);
    ++used;
  }
  r.acf_rmse = used > 0 ? std::sqrt(ss / used) : 0.0;
}

}  // namespace fit_detail

using namespace fit_detail;

Eigen::VectorXd FateHmm::stationary() const {
  if (transition.rows() == 1) return Eigen::VectorXd::Ones(1);
  return stationary_law(transition);
}

std::vector<int> fate_symbols(const std::vector<std::optional<std::int64_t>>& trace) {
  std::vector<int> s;
  s.reserve(trace.size());
  for (const auto& d : trace) {
    if (d && (*d < 0 || *d > kMaxFitDelay)) {
      throw std::out_of_range(
          fmt::format("packet {}: delay {} periods, above the {} the fit families hold", s.size(),
                      *d, kMaxFitDelay));
    }
    s.push_back(d ? static_cast<int>(*d) + 1 : 0);
  }
  return s;
}

double hmm_loglik(const FateHmm& hmm, const std::vector<int>& symbols) {
  std::vector<double> alpha, scale;
  return e_step(hmm, symbols, nullptr, nullptr, alpha, scale);
}

std::size_t best_fit(const std::vector<FitResult>& fits, const std::string& criterion) {
  // A family whose EM stopped at its cap is not at a maximum: it never wins over one that is.
  bool any_converged = false;
  for (const auto& f : fits) any_converged = any_converged || f.converged;
  std::size_t best = fits.size();
  for (std::size_t i = 0; i < fits.size(); ++i) {
    if (any_converged && !fits[i].converged) continue;
    if (best == fits.size()) {
      best = i;
      continue;
    }
    const double a = criterion == "aic" ? fits[i].aic : fits[i].bic;
    const double b = criterion == "aic" ? fits[best].aic : fits[best].bic;
    if (a < b - 1e-6 * std::max(1.0, std::abs(b))) best = i;  // ties: the family listed first
  }
  return best == fits.size() ? 0 : best;
}

std::vector<double> FitResult::marginal_pmf() const {
  const Eigen::VectorXd pi = model.stationary();
  std::vector<double> pmf;
  for (Eigen::Index m = 1; m < model.emission.cols(); ++m)
    pmf.push_back(pi.dot(model.emission.col(m)));
  if (pmf.empty()) pmf.push_back(0.0);
  return pmf;
}

}  // namespace ncosim::models
