// lmi/lmi.cc — expression algebra and the building and validation of a Problem (see lmi.h;
// the translation to CSDP and the solve: csdp.cc; resource limits: limits.cc).
#include "lmi/lmi.h"

#include <Eigen/SparseCore>
#include <algorithm>
#include <atomic>
#include <cmath>
#include <map>
#include <numeric>
#include <sstream>
#include <string>
#include <vector>

#include "lmi/problem_impl.h"

namespace ncosim::lmi {

const char* to_string(Status s) {
  switch (s) {
    case Status::kOptimal:
      return "optimal";
    case Status::kInaccurate:
      return "inaccurate";
    case Status::kInfeasible:
      return "infeasible";
    case Status::kUnbounded:
      return "unbounded";
    case Status::kNumericalTrouble:
      return "numerical_trouble";
    case Status::kInvalidProblem:
      return "invalid_problem";
  }
  return "invalid_problem";
}

// ---------------------------------------------------------------- expressions

Expr::Expr(const Eigen::MatrixXd& constant) : constant_(constant) {}

Expr::Expr(const Var& v) {
  if (v.id < 0) throw Error("lmi: use of an undeclared variable");
  constant_ = Eigen::MatrixXd::Zero(v.rows, v.cols);
  terms_.push_back({v.id, v.problem, false, Eigen::MatrixXd::Identity(v.rows, v.rows),
                    Eigen::MatrixXd::Identity(v.cols, v.cols)});
}

Expr Expr::transpose() const {
  Expr r;
  r.constant_ = constant_.transpose();
  for (const auto& t : terms_)
    r.terms_.push_back({t.var, t.problem, !t.transposed, t.R.transpose(), t.L.transpose()});
  return r;
}

Expr& Expr::operator+=(const Expr& o) {
  if (rows() != o.rows() || cols() != o.cols()) {
    std::ostringstream m;
    m << "lmi: sum of a " << rows() << "x" << cols() << " and a " << o.rows() << "x" << o.cols()
      << " expression";
    throw Error(m.str());
  }
  constant_ += o.constant_;
  terms_.insert(terms_.end(), o.terms_.begin(), o.terms_.end());
  return *this;
}

Expr& Expr::operator-=(const Expr& o) { return *this += -o; }

Expr& Expr::operator*=(double s) {
  constant_ *= s;
  for (auto& t : terms_) t.L *= s;
  return *this;
}

Expr operator+(Expr a, const Expr& b) { return a += b; }
Expr operator-(Expr a, const Expr& b) { return a -= b; }
Expr operator-(const Expr& a) { return -1.0 * a; }
Expr operator*(double s, const Expr& e) {
  Expr r = e;
  return r *= s;
}

Expr Expr::lmul(const Eigen::MatrixXd& m, const Expr& e) {
  if (m.cols() != e.rows()) {
    std::ostringstream s;
    s << "lmi: product of a " << m.rows() << "x" << m.cols() << " matrix and a " << e.rows() << "x"
      << e.cols() << " expression";
    throw Error(s.str());
  }
  Expr r;
  r.constant_ = m * e.constant();
  for (const auto& t : e.terms())
    r.terms_.push_back({t.var, t.problem, t.transposed, m * t.L, t.R});
  return r;
}

Expr Expr::rmul(const Expr& e, const Eigen::MatrixXd& m) {
  if (e.cols() != m.rows()) {
    std::ostringstream s;
    s << "lmi: product of a " << e.rows() << "x" << e.cols() << " expression and a " << m.rows()
      << "x" << m.cols() << " matrix";
    throw Error(s.str());
  }
  Expr r;
  r.constant_ = e.constant() * m;
  for (const auto& t : e.terms())
    r.terms_.push_back({t.var, t.problem, t.transposed, t.L, t.R * m});
  return r;
}

Expr block(const std::vector<std::vector<Expr>>& rows) {
  if (rows.empty() || rows.front().empty()) throw Error("lmi: empty block matrix");
  const std::size_t nc = rows.front().size();
  std::vector<int> heights(rows.size()), widths(nc);
  for (std::size_t i = 0; i < rows.size(); ++i) {
    if (rows[i].size() != nc)
      throw Error("lmi: block matrix rows have different numbers of blocks");
    heights[i] = rows[i][0].rows();
  }
  for (std::size_t j = 0; j < nc; ++j) widths[j] = rows[0][j].cols();
  for (std::size_t i = 0; i < rows.size(); ++i)
    for (std::size_t j = 0; j < nc; ++j)
      if (rows[i][j].rows() != heights[i] || rows[i][j].cols() != widths[j]) {
        std::ostringstream s;
        s << "lmi: block (" << i << "," << j << ") is " << rows[i][j].rows() << "x"
          << rows[i][j].cols() << ", expected " << heights[i] << "x" << widths[j];
        throw Error(s.str());
      }
  const int H = std::accumulate(heights.begin(), heights.end(), 0);
  const int W = std::accumulate(widths.begin(), widths.end(), 0);
  Expr r = Expr(Eigen::MatrixXd::Zero(H, W));
  int r0 = 0;
  for (std::size_t i = 0; i < rows.size(); ++i) {
    int c0 = 0;
    for (std::size_t j = 0; j < nc; ++j) {
      const Expr& e = rows[i][j];
      r.constant_.block(r0, c0, heights[i], widths[j]) += e.constant();
      for (const auto& t : e.terms()) {  // pad L with zero rows and R with zero columns
        Expr::Term p{t.var, t.problem, t.transposed, Eigen::MatrixXd::Zero(H, t.L.cols()),
                     Eigen::MatrixXd::Zero(t.R.rows(), W)};
        p.L.middleRows(r0, heights[i]) = t.L;
        p.R.middleCols(c0, widths[j]) = t.R;
        r.terms_.push_back(std::move(p));
      }
      c0 += widths[j];
    }
    r0 += heights[i];
  }
  return r;
}

Expr block(std::initializer_list<std::initializer_list<Expr>> rows) {
  std::vector<std::vector<Expr>> v;
  for (const auto& row : rows) v.emplace_back(row);
  return block(v);
}

LinearForm trace(const Expr& e) {
  if (e.rows() != e.cols()) throw Error("lmi: trace of a non-square expression");
  LinearForm f;
  f.parts.emplace_back(e, Eigen::MatrixXd::Identity(e.rows(), e.cols()));
  return f;
}

LinearForm entry(const Expr& e, int i, int j) {
  if (i < 0 || j < 0 || i >= e.rows() || j >= e.cols()) throw Error("lmi: entry out of range");
  LinearForm f;
  Eigen::MatrixXd w = Eigen::MatrixXd::Zero(e.rows(), e.cols());
  w(i, j) = 1.0;
  f.parts.emplace_back(e, w);
  return f;
}

LinearForm operator+(LinearForm a, const LinearForm& b) {
  a.constant += b.constant;
  a.parts.insert(a.parts.end(), b.parts.begin(), b.parts.end());
  return a;
}
LinearForm operator*(double s, LinearForm f) {
  f.constant *= s;
  for (auto& p : f.parts) p.second *= s;
  return f;
}
LinearForm operator-(LinearForm a, const LinearForm& b) { return a + (-1.0) * b; }

Constraint operator>=(const Expr& a, const Expr& b) { return Constraint{a - b, false, -1.0, {}}; }
Constraint operator<=(const Expr& a, const Expr& b) { return Constraint{b - a, false, -1.0, {}}; }
Constraint operator>(const Expr& a, const Expr& b) { return Constraint{a - b, true, -1.0, {}}; }
Constraint operator<(const Expr& a, const Expr& b) { return Constraint{b - a, true, -1.0, {}}; }

namespace {
void require_zero(double z) {
  if (z != 0.0) throw Error("lmi: compare an expression with 0 or with another expression");
}
}  // namespace
Constraint operator>=(const Expr& a, double z) {
  require_zero(z);
  return Constraint{a, false, -1.0, {}};
}
Constraint operator>(const Expr& a, double z) {
  require_zero(z);
  return Constraint{a, true, -1.0, {}};
}
Constraint operator<=(const Expr& a, double z) {
  require_zero(z);
  return Constraint{-a, false, -1.0, {}};
}
Constraint operator<(const Expr& a, double z) {
  require_zero(z);
  return Constraint{-a, true, -1.0, {}};
}

Constraint lmi(Constraint c, double margin, std::string name) {
  if (margin >= 0.0) {
    c.margin = margin;
  }
  if (!name.empty()) c.name = std::move(name);
  return c;
}

// ---------------------------------------------------------------- problem

Problem::Problem(Options options) : impl_(std::make_unique<Impl>()) {
  static std::atomic<long> next{1};
  impl_->serial = next++;
  impl_->opt = options;
}
Problem::~Problem() = default;
Problem::Problem(Problem&&) noexcept = default;
Problem& Problem::operator=(Problem&&) noexcept = default;
Options& Problem::options() { return impl_->opt; }

Var Problem::symmetric(int n, std::string name) {
  if (n <= 0) throw Error("lmi: a symmetric variable needs a positive size");
  Var v{static_cast<int>(impl_->vars.size()), n, n, true, impl_->serial};
  impl_->vars.push_back(v);
  impl_->names.push_back(name.empty() ? "X" + std::to_string(v.id) : std::move(name));
  impl_->offset.push_back(impl_->nraw);
  const int cnt = n * (n + 1) / 2;
  for (int i = 0; i < cnt; ++i) impl_->parent.push_back(impl_->nraw + i);
  impl_->nraw += cnt;
  return v;
}

Var Problem::full(int rows, int cols, std::string name) {
  if (rows <= 0 || cols <= 0) throw Error("lmi: a full variable needs positive sizes");
  Var v{static_cast<int>(impl_->vars.size()), rows, cols, false, impl_->serial};
  impl_->vars.push_back(v);
  impl_->names.push_back(name.empty() ? "X" + std::to_string(v.id) : std::move(name));
  impl_->offset.push_back(impl_->nraw);
  for (int i = 0; i < rows * cols; ++i) impl_->parent.push_back(impl_->nraw + i);
  impl_->nraw += rows * cols;
  return v;
}

void Problem::equal(const Var& x, const Var& y) {
  if (!impl_->owns(x) || !impl_->owns(y))
    throw Error("lmi: equal() of a variable of another problem");
  if (x.rows != y.rows || x.cols != y.cols || x.symmetric != y.symmetric)
    throw Error("lmi: equal() needs two variables of the same shape and kind");
  for (int b = 0; b < x.cols; ++b)
    for (int a = 0; a < x.rows; ++a) {
      if (x.symmetric && a > b) continue;
      const int rx = impl_->find(impl_->raw(x, a, b)), ry = impl_->find(impl_->raw(y, a, b));
      if (rx != ry) impl_->parent[std::max(rx, ry)] = std::min(rx, ry);
    }
}

int Problem::add(Constraint c) {
  const Expr& e = c.expr;
  for (const auto& t : e.terms())
    if (t.problem != impl_->serial)
      throw Error("lmi: constraint uses a variable of another problem");
  if (e.rows() != e.cols()) {
    std::ostringstream s;
    s << "lmi: an LMI needs a square expression, got " << e.rows() << "x" << e.cols();
    throw Error(s.str());
  }
  {
    // Resource estimate before expanding: the coefficient of V(i, j) in L V R is the outer
    // product of L's column i and R's row j, so a term expands to at most nnz(L) nnz(R) entries
    // (twice for a transposed or symmetric use), each stored about three times (expansion,
    // translation, CSDP's sparse blocks) at ~16 bytes.
    double entries = 0.0;
    for (const auto& t : e.terms()) {
      const auto nl = static_cast<double>((t.L.array() != 0.0).count());
      const auto nr = static_cast<double>((t.R.array() != 0.0).count());
      entries += 2.0 * nl * nr;
    }
    const double m = e.rows();
    impl_->coef_bytes += 48.0 * entries + 8.0 * m * m;
    impl_->block_bytes += 8.0 * m * m;
    impl_->block_flops += m * m * m;
    impl_->largest_block = std::max(impl_->largest_block, e.rows());
    impl_->check_resources();
  }
  Expanded x;
  x.name = c.name.empty() ? "LMI " + std::to_string(impl_->cons.size()) : c.name;
  x.strict = c.strict;
  x.margin = c.strict ? (c.margin >= 0.0 ? c.margin : -1.0) : 0.0;
  const double tol = impl_->opt.symmetry_tolerance;
  auto check_sym = [&](const Eigen::MatrixXd& M, const std::string& what) {
    const double scale = std::max(1.0, M.cwiseAbs().maxCoeff());
    if ((M - M.transpose()).cwiseAbs().maxCoeff() > tol * scale)
      throw Error("lmi: " + x.name + " is not symmetric (" + what + ")");
  };
  if (e.rows() > 0) check_sym(e.constant(), "constant part");
  x.F0 = 0.5 * (e.constant() + e.constant().transpose());
  impl_->expand(e, x.F);
  for (auto& [k, M] : x.F) {
    const double m = max_abs(M);
    if (!std::isfinite(m)) throw Error("lmi: " + x.name + " has a non-finite coefficient");
    if (asymmetry(M) > tol * std::max(1.0, m))
      throw Error("lmi: " + x.name + " is not symmetric (coefficient of " + impl_->describe(k) +
                  ")");
    M = 0.5 * (M + Sparse(M.transpose()));
    M.prune(0.0);
  }
  if (!x.F0.allFinite()) throw Error("lmi: " + x.name + " has a non-finite constant");
  impl_->cons.push_back(std::move(x));
  return static_cast<int>(impl_->cons.size()) - 1;
}

void Problem::minimize(const LinearForm& f) {
  impl_->objective_raw(f, 1.0);
  impl_->objective_sign = 1.0;
}
void Problem::maximize(const LinearForm& f) {
  impl_->objective_raw(f, -1.0);
  impl_->objective_sign = -1.0;
}

// ---------------------------------------------------------------- values

Eigen::MatrixXd Solution::value(const Var& v) const {
  if (v.id < 0 || v.id >= static_cast<int>(vars_.size()) || vars_[v.id].problem != v.problem ||
      y_.size() == 0)
    throw Error("lmi: value() of an unknown variable or of an unsolved problem");
  Eigen::MatrixXd M(v.rows, v.cols);
  for (int b = 0; b < v.cols; ++b)
    for (int a = 0; a < v.rows; ++a) {
      int r;
      if (v.symmetric) {
        const int lo = std::min(a, b), hi = std::max(a, b);
        r = var_offset_[v.id] + hi * (hi + 1) / 2 + lo;
      } else {
        r = var_offset_[v.id] + a + b * v.rows;
      }
      M(a, b) = y_(solver_of_[r]);
    }
  return M;
}

Eigen::MatrixXd Solution::value(const Expr& e) const {
  Eigen::MatrixXd M = e.constant();
  for (const auto& t : e.terms()) {
    Eigen::MatrixXd V = value(vars_.at(t.var));
    M += t.L * (t.transposed ? Eigen::MatrixXd(V.transpose()) : V) * t.R;
  }
  return M;
}

double Solution::value(const LinearForm& f) const {
  double x = f.constant;
  for (const auto& [e, w] : f.parts) x += (w.array() * value(e).array()).sum();
  return x;
}

}  // namespace ncosim::lmi
