// estimators/kalman_update.cc — the Kalman kernel (see the header). The loops are written once
// as templates on the state size N (0: run-time size) over column-major storage; the dispatch
// instantiates N = 1..8.
#include "estimators/kalman_update.h"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace ncosim::est::kalman {

namespace {

using Index = Eigen::Index;

// Above this state size the prediction uses Eigen's blocked products (cache blocking pays).
constexpr Index kLoopMax = 16;

template <int N>
void predict_covariance_loops(const double* a, const double* q, double* p, double* t, Index n_rt) {
  const Index n = N > 0 ? N : n_rt;
  for (Index c = 0; c < n; ++c) {  // t = A P
    for (Index r = 0; r < n; ++r) {
      double acc = 0.0;
      for (Index k = 0; k < n; ++k) acc += a[k * n + r] * p[c * n + k];
      t[c * n + r] = acc;
    }
  }
  for (Index c = 0; c < n; ++c) {  // lower triangle of t A' + Q, mirrored
    for (Index r = c; r < n; ++r) {
      double acc = 0.0;
      for (Index k = 0; k < n; ++k) acc += t[k * n + r] * a[k * n + c];
      const double v = acc + 0.5 * (q[c * n + r] + q[r * n + c]);
      p[c * n + r] = v;
      p[r * n + c] = v;
    }
  }
}

template <int N>
void predict_state_loops(const double* a, double* x, double* t, Index n_rt) {
  const Index n = N > 0 ? N : n_rt;
  for (Index r = 0; r < n; ++r) {
    double acc = 0.0;
    for (Index k = 0; k < n; ++k) acc += a[k * n + r] * x[k];
    t[r] = acc;
  }
  for (Index r = 0; r < n; ++r) x[r] = t[r];
}

struct FactorArgs {
  const double* x;
  const double* p;
  const double* c;  // leading dimension ld
  const double* rr;
  const double* y;
  double* l;
  double* u;
  double* w;
  Index ld;  // rows of C, R, L, U (m_max)
  Index m;
  Index n;
};

template <int N>
Factor factor_loops(const FactorArgs& f) {
  const Index n = N > 0 ? N : f.n;
  const Index m = f.m, ld = f.ld;
  const double *c = f.c, *p = f.p, *x = f.x;
  double *l = f.l, *u = f.u, *w = f.w;
  for (Index a = 0; a < m; ++a) {  // w = y - C x
    double acc = 0.0;
    for (Index k = 0; k < n; ++k) acc += c[k * ld + a] * x[k];
    w[a] = f.y[a] - acc;
  }
  for (Index j = 0; j < n; ++j) {  // U = C P
    for (Index a = 0; a < m; ++a) {
      double acc = 0.0;
      for (Index k = 0; k < n; ++k) acc += c[k * ld + a] * p[j * n + k];
      u[j * ld + a] = acc;
    }
  }
  bool finite = true;
  for (Index b = 0; b < m; ++b) {  // lower triangle of S = U C' + R
    for (Index a = b; a < m; ++a) {
      double acc = 0.0;
      for (Index k = 0; k < n; ++k) acc += u[k * ld + a] * c[k * ld + b];
      const double s = acc + f.rr[b * ld + a];
      l[b * ld + a] = s;
      finite = finite && std::isfinite(s);
    }
    finite = finite && std::isfinite(w[b]);
  }
  if (!finite) return Factor::kNonFinite;
  for (Index j = 0; j < m; ++j) {  // Cholesky S = L L', in place
    double d = l[j * ld + j];
    for (Index k = 0; k < j; ++k) d -= l[k * ld + j] * l[k * ld + j];
    if (!(d > 0.0)) return Factor::kNotPositiveDefinite;
    const double ljj = std::sqrt(d);
    l[j * ld + j] = ljj;
    for (Index i = j + 1; i < m; ++i) {
      double s = l[j * ld + i];
      for (Index k = 0; k < j; ++k) s -= l[k * ld + i] * l[k * ld + j];
      l[j * ld + i] = s / ljj;
    }
  }
  for (Index r = 0; r < m; ++r) {  // w <- L^-1 w, U <- L^-1 U (forward substitution)
    const double lrr = l[r * ld + r];
    double s = w[r];
    for (Index k = 0; k < r; ++k) s -= l[k * ld + r] * w[k];
    w[r] = s / lrr;
    for (Index j = 0; j < n; ++j) {
      double v = u[j * ld + r];
      for (Index k = 0; k < r; ++k) v -= l[k * ld + r] * u[j * ld + k];
      u[j * ld + r] = v / lrr;
    }
  }
  return Factor::kOk;
}

template <int N>
void apply_loops(double* x, double* p, const double* u, const double* w, Index ld, Index m,
                 Index n_rt) {
  const Index n = N > 0 ? N : n_rt;
  for (Index j = 0; j < n; ++j) {  // x += U' w
    double acc = 0.0;
    for (Index a = 0; a < m; ++a) acc += u[j * ld + a] * w[a];
    x[j] += acc;
  }
  for (Index c = 0; c < n; ++c) {  // P -= U' U, lower triangle mirrored
    for (Index r = c; r < n; ++r) {
      double acc = 0.0;
      for (Index a = 0; a < m; ++a) acc += u[r * ld + a] * u[c * ld + a];
      const double v = p[c * n + r] - acc;
      p[c * n + r] = v;
      p[r * n + c] = v;
    }
  }
}

// Calls body.template operator()<N>() with N = n for n in 1..8, else N = 0.
template <class Body>
decltype(auto) dispatch(Index n, Body&& body) {
  switch (n) {
    case 1:
      return body.template operator()<1>();
    case 2:
      return body.template operator()<2>();
    case 3:
      return body.template operator()<3>();
    case 4:
      return body.template operator()<4>();
    case 5:
      return body.template operator()<5>();
    case 6:
      return body.template operator()<6>();
    case 7:
      return body.template operator()<7>();
    case 8:
      return body.template operator()<8>();
    default:
      return body.template operator()<0>();
  }
}

}  // namespace

void Workspace::reserve(Index n, Index m_max) {
  m_max = std::max<Index>(m_max, 1);
  C = Eigen::MatrixXd::Zero(m_max, n);
  R = Eigen::MatrixXd::Zero(m_max, m_max);
  y = Eigen::VectorXd::Zero(m_max);
  L = Eigen::MatrixXd::Zero(m_max, m_max);
  U = Eigen::MatrixXd::Zero(m_max, n);
  w = Eigen::VectorXd::Zero(m_max);
  T = Eigen::MatrixXd::Zero(n, n);
  xt = Eigen::VectorXd::Zero(n);
  m = 0;
}

double Workspace::log_likelihood() const {
  double sq = 0.0;
  for (Index a = 0; a < m; ++a) sq += w(a) * w(a);
  // log det S / 2 = sum log L_ii, here rather than in factor(): most filters never ask.
  double half_log_det = 0.0;
  for (Index j = 0; j < m; ++j) half_log_det += std::log(L(j, j));
  return -0.5 * sq - half_log_det - 0.5 * static_cast<double>(m) * std::log(2.0 * std::numbers::pi);
}

void predict_covariance(const Eigen::MatrixXd& A, const Eigen::MatrixXd& Q, Eigen::MatrixXd& P,
                        Workspace& ws) {
  const Index n = P.rows();
  if (n > kLoopMax) {
    ws.T.noalias() = A * P;
    P.noalias() = ws.T * A.transpose();
    P += Q;
    for (Index c = 0; c < n; ++c) {
      for (Index r = c + 1; r < n; ++r) {
        const double v = 0.5 * (P(r, c) + P(c, r));
        P(r, c) = v;
        P(c, r) = v;
      }
    }
    return;
  }
  dispatch(n, [&]<int N>() {
    predict_covariance_loops<N>(A.data(), Q.data(), P.data(), ws.T.data(), n);
  });
}

void predict_state(const Eigen::MatrixXd& A, Eigen::VectorXd& x, Workspace& ws) {
  const Index n = x.size();
  dispatch(n, [&]<int N>() { predict_state_loops<N>(A.data(), x.data(), ws.xt.data(), n); });
}

Index select(const Eigen::MatrixXd& C, const Eigen::MatrixXd& R, const Eigen::VectorXd& y,
             const Index* rows, Index m, Workspace& ws) {
  for (Index a = 0; a < m; ++a) {
    const Index ra = rows[a];
    ws.C.row(a) = C.row(ra);
    ws.y(a) = y(ra);
    for (Index b = 0; b < m; ++b) ws.R(a, b) = R(ra, rows[b]);
  }
  ws.m = m;
  return m;
}

Factor factor(const Eigen::VectorXd& x, const Eigen::MatrixXd& P, Workspace& ws) {
  const FactorArgs f{x.data(),    P.data(),    ws.C.data(), ws.R.data(), ws.y.data(), ws.L.data(),
                     ws.U.data(), ws.w.data(), ws.C.rows(), ws.m,        P.rows()};
  return dispatch(P.rows(), [&]<int N>() { return factor_loops<N>(f); });
}

void apply(Eigen::VectorXd& x, Eigen::MatrixXd& P, const Workspace& ws) {
  const Index n = P.rows();
  dispatch(n, [&]<int N>() {
    apply_loops<N>(x.data(), P.data(), ws.U.data(), ws.w.data(), ws.U.rows(), ws.m, n);
  });
}

void apply_pseudo_inverse(Eigen::VectorXd& x, Eigen::MatrixXd& P, const Workspace& ws) {
  const Index m = ws.m;
  const auto Cs = ws.C.topRows(m);
  const Eigen::MatrixXd Rs = ws.R.topLeftCorner(m, m).selfadjointView<Eigen::Lower>();
  const Eigen::MatrixXd PCt = P * Cs.transpose();
  const Eigen::MatrixXd S = Cs * PCt + Rs;
  const Eigen::MatrixXd K = PCt * S.completeOrthogonalDecomposition().pseudoInverse();
  const Eigen::VectorXd r = ws.y.head(m) - Cs * x;
  x.noalias() += K * r;
  P.noalias() -= K * PCt.transpose();
  P = 0.5 * (P + P.transpose()).eval();
}

bool update(Eigen::VectorXd& x, Eigen::MatrixXd& P, Workspace& ws, Innovations* counted) {
  switch (factor(x, P, ws)) {
    case Factor::kOk:
      if (counted != nullptr) {
        counted->nis += ws.w.head(ws.m).squaredNorm();
        counted->dof += ws.m;
        ++counted->updates;
      }
      apply(x, P, ws);
      return true;
    case Factor::kNotPositiveDefinite:
      apply_pseudo_inverse(x, P, ws);
      return true;
    case Factor::kNonFinite:
      return false;
  }
  return false;
}

}  // namespace ncosim::est::kalman
