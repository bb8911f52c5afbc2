// lmi/lmi.cc — expression algebra, validation, and the translation to CSDP (see lmi.h).
#include "lmi/lmi.h"

#include <sys/mman.h>
#include <sys/resource.h>
#include <unistd.h>

#include <Eigen/Eigenvalues>
#include <Eigen/SparseCore>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <iomanip>
#include <map>
#include <mutex>
#include <numeric>
#include <sstream>

#include "lmi/limits.h"

extern "C" {
#include <csdp/declarations.h>
}

namespace {
// CSDP's parameters for the solve in progress (guarded by csdp_mutex()). CSDP's own
// initparams() reads ./param.csdp and defaults printlevel to 1; this definition, found
// before libsdp's by the dynamic linker, supplies ours instead (tests/lmi: "param.csdp in
// the working directory is ignored" and "max_iterations reaches CSDP").
paramstruc g_params{};
int g_printlevel = 0;

std::mutex& csdp_mutex() {
  static std::mutex m;
  return m;
}
}  // namespace

extern "C" void initparams(struct paramstruc* params, int* pprintlevel) {
  *params = g_params;
  *pprintlevel = g_printlevel;
}

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

namespace {
using Sparse = Eigen::SparseMatrix<double>;

// max |M - M'| of a sparse matrix (0 for an empty one).
double asymmetry(const Sparse& M) {
  Sparse D = M - Sparse(M.transpose());
  double m = 0.0;
  for (int k = 0; k < D.outerSize(); ++k)
    for (Sparse::InnerIterator it(D, k); it; ++it) m = std::max(m, std::abs(it.value()));
  return m;
}
// Above this magnitude, problem data are refused (translate()).
constexpr double kMaxDataMagnitude = 1e100;

double max_abs(const Sparse& M) {
  double m = 0.0;
  for (int k = 0; k < M.outerSize(); ++k)
    for (Sparse::InnerIterator it(M, k); it; ++it) m = std::max(m, std::abs(it.value()));
  return m;
}

// An LMI expanded over raw scalars: F0 + sum_k y_k F_k (F_k symmetric, only nonzero kept).
struct Expanded {
  Eigen::MatrixXd F0;
  std::map<int, Sparse> F;  // raw scalar -> coefficient
  bool strict = false;
  double margin = 0.0;
  std::string name;
};
}  // namespace

struct Problem::Impl {
  long serial = 0;
  Options opt;
  std::vector<Var> vars;
  std::vector<std::string> names;
  std::vector<int> offset;  // first raw scalar per variable
  int nraw = 0;
  std::vector<int> parent;  // union-find over raw scalars (equal())
  std::vector<Expanded> cons;
  bool has_objective = false;
  double objective_sign = 1.0;
  Eigen::VectorXd c;  // raw objective coefficients (of the minimised form)
  double c0 = 0.0;
  double coef_bytes = 0.0;   // estimated memory of the expanded coefficients (resource limits)
  double block_bytes = 0.0;  // sum over LMIs of 8 m^2
  double block_flops = 0.0;  // sum over LMIs of m^3
  int largest_block = 0;

  // The memory and work of a solve (CSDP), estimated from the sizes above.
  SolveEstimate estimate() const;
  // Throws ResourceLimitError when the estimate of a solve exceeds the process-wide limits.
  void check_resources() const;

  bool owns(const Var& v) const {
    return v.problem == serial && v.id >= 0 && v.id < static_cast<int>(vars.size());
  }
  int find(int k) {
    while (parent[k] != k) k = parent[k] = parent[parent[k]];
    return k;
  }
  int find_const(int k) const {
    while (parent[k] != k) k = parent[k];
    return k;
  }

  // Raw scalar index of entry (a, b) of variable v (symmetric: a <= b).
  int raw(const Var& v, int a, int b) const {
    if (v.symmetric) {
      if (a > b) std::swap(a, b);
      return offset[v.id] + b * (b + 1) / 2 + a;
    }
    return offset[v.id] + a + b * v.rows;
  }

  std::string describe(int k) const {
    for (const auto& v : vars) {
      const int n = v.symmetric ? v.rows * (v.rows + 1) / 2 : v.rows * v.cols;
      if (k >= offset[v.id] && k < offset[v.id] + n)
        for (int b = 0; b < v.cols; ++b)
          for (int a = 0; a < v.rows; ++a)
            if ((!v.symmetric || a <= b) && raw(v, a, b) == k) {
              std::ostringstream s;
              s << "'" << names[v.id] << "' entry (" << a << "," << b << ")";
              return s.str();
            }
    }
    return "?";
  }

  // Calls fn(k, M) with the (sparse) coefficient matrix M of raw scalar k, for each term L V(') R.
  template <typename Fn>
  void for_each_coefficient(const Expr& e, Fn&& fn) const {
    std::vector<Eigen::Triplet<double>> trip;
    for (const auto& t : e.terms()) {
      const Var& v = vars[t.var];
      // Nonzero rows of each column of L and nonzero columns of each row of R.
      std::vector<std::vector<int>> lnz(t.L.cols()), rnz(t.R.rows());
      for (Eigen::Index q = 0; q < t.L.cols(); ++q)
        for (Eigen::Index r = 0; r < t.L.rows(); ++r)
          if (t.L(r, q) != 0.0) lnz[q].push_back(static_cast<int>(r));
      for (Eigen::Index q = 0; q < t.R.cols(); ++q)
        for (Eigen::Index r = 0; r < t.R.rows(); ++r)
          if (t.R(r, q) != 0.0) rnz[r].push_back(static_cast<int>(q));
      auto outer = [&](int col, int row) {
        for (int i : lnz[col])
          for (int j : rnz[row]) trip.emplace_back(i, j, t.L(i, col) * t.R(row, j));
      };
      for (int b = 0; b < v.cols; ++b)
        for (int a = 0; a < v.rows; ++a) {
          if (v.symmetric && a > b) continue;
          // Basis E_ab (+ E_ba when symmetric off-diagonal); transposed swaps the roles.
          const int ra = t.transposed ? b : a, cb = t.transposed ? a : b;
          trip.clear();
          outer(ra, cb);
          if (v.symmetric && a != b) outer(cb, ra);
          if (trip.empty()) continue;
          Sparse M(t.L.rows(), t.R.cols());
          M.setFromTriplets(trip.begin(), trip.end());
          fn(raw(v, a, b), std::move(M));
        }
    }
  }

  void expand(const Expr& e, std::map<int, Sparse>& out) const {
    for_each_coefficient(e, [&](int k, Sparse&& M) {
      auto it = out.find(k);
      if (it == out.end())
        out.emplace(k, std::move(M));
      else
        it->second += M;
    });
  }

  void objective_raw(const LinearForm& f, double sign) {
    c = Eigen::VectorXd::Zero(nraw);
    c0 = sign * f.constant;
    for (const auto& part : f.parts) {
      const auto& e = part.first;
      const auto& w =
          part.second;  // a reference, not a structured binding: lambdas capture it (clang 14)
      if (w.rows() != e.rows() || w.cols() != e.cols())
        throw Error("lmi: objective weight shape mismatch");
      for (const auto& t : e.terms())
        if (t.problem != serial) throw Error("lmi: objective uses a variable of another problem");
      c0 += sign * (w.array() * e.constant().array()).sum();
      for_each_coefficient(e, [&](int k, Sparse&& M) {
        double x = 0.0;
        for (int o = 0; o < M.outerSize(); ++o)
          for (Sparse::InnerIterator it(M, o); it; ++it) x += w(it.row(), it.col()) * it.value();
        c(k) += sign * x;
      });
    }
    has_objective = true;
  }
};

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

namespace {
std::mutex& limits_mutex() {
  static std::mutex m;
  return m;
}
ResourceLimits& limits_storage() {
  static ResourceLimits l;
  return l;
}
std::string human(double bytes) {
  char buf[64];
  if (bytes >= 1e9)
    std::snprintf(buf, sizeof buf, "%.1f GB", bytes / 1e9);
  else
    std::snprintf(buf, sizeof buf, bytes >= 1e8 ? "%.0f MB" : "%.3g MB", bytes / 1e6);
  return buf;
}

// Whole GFLOP from 100 on, else three significant digits (a limit of 0.01 GFLOP is not "0").
std::string gflop(double flops) {
  char buf[64];
  std::snprintf(buf, sizeof buf, flops >= 1e11 ? "%.0f GFLOP" : "%.3g GFLOP", flops / 1e9);
  return buf;
}

thread_local std::function<void(const SolveEstimate&)> t_solve_observer;

// The process's address-space limit in bytes (RLIMIT_AS), 0 when unlimited.
double address_space_limit() {
  struct rlimit rl {};
  if (::getrlimit(RLIMIT_AS, &rl) != 0 || rl.rlim_cur == RLIM_INFINITY) return 0.0;
  return static_cast<double>(rl.rlim_cur);
}

// CSDP calls exit(205) when its malloc fails (libsdp: "Storage allocation failed!", printed to
// the captured stdout): while a solve runs, an exit is turned into exit 1 with a message.
std::atomic<bool> g_in_csdp{false};
void exit_during_csdp() {
  if (!g_in_csdp.load()) return;
  static const char kMessage[] =
      "ncosim: error: out of memory in the LMI solver (CSDP ends the process when its allocation "
      "fails) beyond "
      "what the resource estimates foresaw; lower the design's size or free memory\n";
  (void)!::write(2, kMessage, sizeof kMessage - 1);
  ::_exit(1);
}
}  // namespace

ScopedSolveObserver::ScopedSolveObserver(std::function<void(const SolveEstimate&)> observer)
    : previous_(std::move(t_solve_observer)) {
  t_solve_observer = std::move(observer);
}
ScopedSolveObserver::~ScopedSolveObserver() { t_solve_observer = std::move(previous_); }

void set_resource_limits(const ResourceLimits& limits) {
  std::lock_guard<std::mutex> g(limits_mutex());
  limits_storage() = limits;
}

ResourceLimits resource_limits() {
  std::lock_guard<std::mutex> g(limits_mutex());
  return limits_storage();
}

SolveEstimate Problem::Impl::estimate() const {
  const double k = nraw;
  // CSDP: the Schur complement O (k x k) and its factor, k-vectors, and about 11 copies of the
  // block-diagonal X (X, Z, dX, dZ, work matrices); the expanded coefficients.
  const double bytes = 16.0 * k * k + 11.0 * block_bytes + coef_bytes;
  // 50 iterations of: Schur complement k^2 * (largest block), Cholesky k^3 / 3, block work.
  const double flops =
      50.0 * (k * k * std::max(1, largest_block) + k * k * k / 3.0 + 10.0 * block_flops);
  return SolveEstimate{bytes, flops, nraw, largest_block};
}

void Problem::Impl::check_resources() const {
  const ResourceLimits lim = resource_limits();
  const SolveEstimate e = estimate();
  const double bytes = e.bytes, flops = e.flops;
  const bool over_memory = lim.memory_bytes > 0.0 && bytes > lim.memory_bytes;
  const bool over_work = lim.work_flops > 0.0 && flops > lim.work_flops;
  const double address_space = address_space_limit();
  if (!over_memory && address_space > 0.0 && bytes > address_space) {
    throw ResourceLimitError(
        "an LMI problem of " + std::to_string(nraw) + " scalar variables (largest block " +
            std::to_string(largest_block) + ") needs an estimated " + human(bytes) +
            ", above the process's address-space limit of " + human(address_space) +
            " (ulimit -v; the solver would end the process when its allocation fails)",
        bytes, flops, nraw, largest_block, true);
  }
  if (!over_memory && !over_work) return;
  std::string what =
      over_memory
          ? "an LMI problem of " + std::to_string(nraw) + " scalar variables (largest block " +
                std::to_string(largest_block) + ") needs an estimated " + human(bytes) +
                ", above the memory limit of " + human(lim.memory_bytes)
          : "an LMI problem of " + std::to_string(nraw) + " scalar variables (largest block " +
                std::to_string(largest_block) + ") needs an estimated " + gflop(flops) +
                ", above the work limit of " + gflop(lim.work_flops);
  throw ResourceLimitError(what, bytes, flops, nraw, largest_block);
}

// ---------------------------------------------------------------- translation

namespace {
struct Translation {
  std::vector<int> solver_of;      // raw -> solver var (-1 unused)
  int k = 0;                       // solver vars
  std::vector<int> matrix_cons;    // constraint indices in matrix blocks
  std::vector<int> scalar_cons;    // 1x1 constraints in the diagonal block
  std::vector<int> constant_cons;  // variable-free constraints
  // per constraint: solver var -> coefficient (aliases summed)
  std::vector<std::map<int, Sparse>> coef;
  SdpSize size;
  std::string error;
};

Translation translate(Problem::Impl& p) {
  Translation t;
  if (p.vars.empty()) {
    t.error = "the problem has no variables";
    return t;
  }
  t.solver_of.assign(p.nraw, -1);
  std::vector<int> rep_solver(p.nraw, -1);
  for (int r = 0; r < p.nraw; ++r) {
    const int root = p.find(r);
    if (rep_solver[root] < 0) rep_solver[root] = t.k++;
    t.solver_of[r] = rep_solver[root];
  }
  t.coef.resize(p.cons.size());
  std::vector<bool> used(t.k, false);
  for (std::size_t i = 0; i < p.cons.size(); ++i) {
    const auto& c = p.cons[i];
    if (c.F0.rows() == 0) {
      t.error = c.name + " is empty (0x0)";
      return t;
    }
    for (const auto& [r, M] : c.F) {
      const int s = t.solver_of[r];
      auto it = t.coef[i].find(s);
      if (it == t.coef[i].end())
        t.coef[i].emplace(s, M);
      else
        it->second += M;
    }
    for (auto it = t.coef[i].begin(); it != t.coef[i].end();) {
      it->second.prune(0.0);
      if (it->second.nonZeros() == 0)
        it = t.coef[i].erase(it);
      else {
        used[it->first] = true;
        ++it;
      }
    }
    if (t.coef[i].empty())
      t.constant_cons.push_back(static_cast<int>(i));
    else if (c.F0.rows() == 1)
      t.scalar_cons.push_back(static_cast<int>(i));
    else
      t.matrix_cons.push_back(static_cast<int>(i));
  }
  if (t.matrix_cons.empty() && t.scalar_cons.empty()) {
    t.error = "no constraint involves a variable";
    return t;
  }
  // CSDP multiplies the data with each other and with its iterates; beyond kMaxDataMagnitude
  // those products overflow, and CSDP 6.2 can then loop without end instead of reporting
  // NaN or Inf (found by the structured fuzzer: a plant Bw entry of 1e200 in a sod_jump design).
  auto too_large = [](const std::string& what, double m) {
    std::ostringstream os;
    os << what << " has a coefficient of magnitude " << std::setprecision(3) << m << ", above "
       << kMaxDataMagnitude
       << ": the solver's arithmetic would overflow (rescale the model: its matrices or units)";
    return os.str();
  };
  for (std::size_t i = 0; i < p.cons.size(); ++i) {
    double m = p.cons[i].F0.cwiseAbs().maxCoeff();
    for (const auto& [s, M] : t.coef[i]) m = std::max(m, max_abs(M));
    if (m > kMaxDataMagnitude) {
      t.error = too_large(p.cons[i].name, m);
      return t;
    }
  }
  if (p.has_objective && p.c.size() > 0 && p.c.cwiseAbs().maxCoeff() > kMaxDataMagnitude) {
    t.error = too_large("the objective", p.c.cwiseAbs().maxCoeff());
    return t;
  }
  for (int r = 0; r < p.nraw; ++r)
    if (!used[t.solver_of[r]]) {
      t.error = "variable " + p.describe(r) +
                " appears in no constraint (CSDP would exit on it; constrain or remove it)";
      return t;
    }
  t.size.variables = t.k;
  for (int i : t.matrix_cons) t.size.block_sizes.push_back(static_cast<int>(p.cons[i].F0.rows()));
  if (!t.scalar_cons.empty()) {
    t.size.block_sizes.push_back(static_cast<int>(t.scalar_cons.size()));
    t.size.diagonal_block = true;
  }
  t.size.blocks = static_cast<int>(t.size.block_sizes.size());
  t.size.total_dimension = std::accumulate(t.size.block_sizes.begin(), t.size.block_sizes.end(), 0);
  return t;
}

double margin_of(const Expanded& c, const Options& o) {
  return c.strict ? (c.margin >= 0.0 ? c.margin : o.strict_margin) : 0.0;
}

double min_eig(const Eigen::MatrixXd& M) {
  if (M.rows() == 1) return M(0, 0);
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(M, Eigen::EigenvaluesOnly);
  return es.eigenvalues().minCoeff();
}

template <typename T>
T* c_alloc(std::size_t n) {
  void* p = std::calloc(n, sizeof(T));
  if (!p) throw std::bad_alloc();
  return static_cast<T*>(p);
}

// stdout (fd 1) redirected into an anonymous memory file for the lifetime of the object.
class StdoutCapture {
 public:
  StdoutCapture() {
    std::fflush(stdout);
    fd_ = memfd_create("ncosim-csdp-log", 0);
    saved_ = dup(1);
    if (fd_ >= 0 && saved_ >= 0) active_ = dup2(fd_, 1) >= 0;
  }
  std::string finish() {
    std::string out;
    std::fflush(stdout);
    if (active_) {
      dup2(saved_, 1);
      active_ = false;
      const off_t len = lseek(fd_, 0, SEEK_END);
      if (len > 0) {
        out.resize(static_cast<std::size_t>(len));
        if (pread(fd_, out.data(), out.size(), 0) != len) out.clear();
      }
    }
    return out;
  }
  ~StdoutCapture() {
    finish();
    if (fd_ >= 0) close(fd_);
    if (saved_ >= 0) close(saved_);
  }
  StdoutCapture(const StdoutCapture&) = delete;
  StdoutCapture& operator=(const StdoutCapture&) = delete;

 private:
  int fd_ = -1, saved_ = -1;
  bool active_ = false;
};

const char* csdp_code_text(int code) {
  switch (code) {
    case 0:
      return "solved";
    case 1:
      return "primal infeasible (the LMI objective is unbounded below)";
    case 2:
      return "dual infeasible (the LMIs are infeasible)";
    case 3:
      return "partial success: solution of reduced accuracy";
    case 4:
      return "maximum iterations reached";
    case 5:
      return "stuck at the edge of primal feasibility";
    case 6:
      return "stuck at the edge of dual infeasibility";
    case 7:
      return "lack of progress";
    case 8:
      return "X, Z or O singular";
    case 9:
      return "NaN or Inf detected";
    default:
      return "unknown CSDP failure";
  }
}
}  // namespace

SdpSize Problem::size() const { return translate(*impl_).size; }

Solution Problem::solve() const {
  Impl& p = *impl_;
  p.check_resources();
  if (t_solve_observer) t_solve_observer(p.estimate());
  Solution sol;
  sol.vars_ = p.vars;
  sol.var_offset_ = p.offset;
  Translation t = translate(p);
  sol.size = t.size;
  sol.solver_of_ = t.solver_of;
  if (!t.error.empty()) {
    sol.status = Status::kInvalidProblem;
    sol.message = t.error;
    return sol;
  }
  // Variable-free constraints: decided here (CSDP would see an empty block).
  for (int i : t.constant_cons) {
    const auto& c = p.cons[i];
    if (min_eig(c.F0) < margin_of(c, p.opt) - 1e-12 * std::max(1.0, c.F0.cwiseAbs().maxCoeff())) {
      sol.status = Status::kInfeasible;
      sol.message = c.name + " involves no variable and does not hold";
      return sol;
    }
  }
  Eigen::VectorXd a = Eigen::VectorXd::Zero(t.k);
  if (p.has_objective) {
    for (int r = 0; r < p.c.size(); ++r) a(t.solver_of[r]) += p.c(r);
  }
  const int k = t.k;
  const int nblocks = t.size.blocks;

  // Build CSDP's data (malloc'd: free_prob releases it).
  blockmatrix C{};
  C.nblocks = nblocks;
  C.blocks = c_alloc<blockrec>(nblocks + 1);
  for (std::size_t b = 0; b < t.matrix_cons.size(); ++b) {
    const auto& c = p.cons[t.matrix_cons[b]];
    const int m = static_cast<int>(c.F0.rows());
    blockrec& br = C.blocks[b + 1];
    br.blockcategory = MATRIX;
    br.blocksize = m;
    br.data.mat = c_alloc<double>(static_cast<std::size_t>(m) * m);
    const double mg = margin_of(c, p.opt);
    for (int j = 0; j < m; ++j)
      for (int i = 0; i < m; ++i) br.data.mat[j * m + i] = -c.F0(i, j) + (i == j ? mg : 0.0);
  }
  if (t.size.diagonal_block) {
    const int m = static_cast<int>(t.scalar_cons.size());
    blockrec& br = C.blocks[nblocks];
    br.blockcategory = DIAG;
    br.blocksize = m;
    br.data.vec = c_alloc<double>(m + 1);
    for (int i = 0; i < m; ++i) {
      const auto& c = p.cons[t.scalar_cons[i]];
      br.data.vec[i + 1] = -c.F0(0, 0) + margin_of(c, p.opt);
    }
  }
  double* ca = c_alloc<double>(k + 1);
  for (int i = 0; i < k; ++i) ca[i + 1] = a(i);
  constraintmatrix* cons = c_alloc<constraintmatrix>(k + 1);
  // Per solver variable, its blocks in increasing block order (prepend in reverse).
  std::vector<std::vector<std::pair<int, std::vector<std::tuple<int, int, double>>>>> per_var(k);
  for (std::size_t b = 0; b < t.matrix_cons.size(); ++b)
    for (const auto& [s, M] : t.coef[t.matrix_cons[b]]) {
      std::vector<std::tuple<int, int, double>> ent;
      for (int o = 0; o < M.outerSize(); ++o)
        for (Sparse::InnerIterator it(M, o); it; ++it)
          if (it.row() <= it.col() && it.value() != 0.0)
            ent.emplace_back(static_cast<int>(it.row()) + 1, static_cast<int>(it.col()) + 1,
                             it.value());
      if (!ent.empty()) per_var[s].emplace_back(static_cast<int>(b) + 1, std::move(ent));
    }
  if (t.size.diagonal_block) {
    std::vector<std::vector<std::tuple<int, int, double>>> diag(k);
    for (std::size_t i = 0; i < t.scalar_cons.size(); ++i)
      for (const auto& [s, M] : t.coef[t.scalar_cons[i]])
        diag[s].emplace_back(static_cast<int>(i) + 1, static_cast<int>(i) + 1, M.coeff(0, 0));
    for (int s = 0; s < k; ++s)
      if (!diag[s].empty()) per_var[s].emplace_back(nblocks, std::move(diag[s]));
  }
  for (int s = 0; s < k; ++s) {
    sparseblock* head = nullptr;
    for (auto it = per_var[s].rbegin(); it != per_var[s].rend(); ++it) {
      auto* sb = c_alloc<sparseblock>(1);
      const int ne = static_cast<int>(it->second.size());
      sb->numentries = ne;
      sb->blocknum = it->first;
      sb->blocksize = C.blocks[it->first].blocksize;
      sb->constraintnum = s + 1;
      sb->entries = c_alloc<double>(ne + 1);
      sb->iindices = c_alloc<int>(ne + 1);
      sb->jindices = c_alloc<int>(ne + 1);
      for (int e = 0; e < ne; ++e) {
        sb->iindices[e + 1] = std::get<0>(it->second[e]);
        sb->jindices[e + 1] = std::get<1>(it->second[e]);
        sb->entries[e + 1] = std::get<2>(it->second[e]);
      }
      sb->next = head;
      head = sb;
    }
    cons[s + 1].blocks = head;
  }

  blockmatrix X{}, Z{};
  double* y = nullptr;
  double pobj = 0.0, dobj = 0.0;
  int code = -1;
  {
    std::lock_guard<std::mutex> lock(csdp_mutex());
    paramstruc prm{};
    prm.axtol = prm.atytol = prm.objtol = p.opt.tolerance;
    prm.pinftol = 1e8;
    prm.dinftol = 1e8;
    prm.maxiter = p.opt.max_iterations;
    prm.minstepfrac = 0.90;
    prm.maxstepfrac = 0.97;
    prm.minstepp = 1e-8;
    prm.minstepd = 1e-8;
    prm.usexzgap = 1;
    prm.tweakgap = 0;
    prm.affine = 0;
    prm.perturbobj = 1.0;
    prm.fastmode = 0;
    g_params = prm;
    g_printlevel = p.opt.verbose ? 1 : 0;
    StdoutCapture capture;
    const auto t0 = std::chrono::steady_clock::now();
    static const bool exit_hook = std::atexit(exit_during_csdp) == 0;
    (void)exit_hook;
    g_in_csdp.store(true);
    initsoln(t.size.total_dimension, k, C, ca, cons, &X, &y, &Z);
    code = easy_sdp(t.size.total_dimension, k, C, ca, cons, 0.0, &X, &y, &Z, &pobj, &dobj);
    g_in_csdp.store(false);
    sol.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    sol.log = capture.finish();
  }
  sol.y_.resize(k);
  for (int i = 0; i < k; ++i) sol.y_(i) = y[i + 1];
  free_prob(t.size.total_dimension, k, C, ca, cons, X, y, Z);

  sol.csdp_code = code;
  const double s = p.objective_sign;
  sol.primal_objective = s * (pobj + p.c0);
  sol.dual_objective = s * (dobj + p.c0);
  sol.objective = s * (0.5 * (pobj + dobj) + p.c0);
  if (!p.has_objective) sol.objective = sol.primal_objective = sol.dual_objective = 0.0;
  switch (code) {
    case 0:
      sol.status = Status::kOptimal;
      break;
    case 1:
      sol.status = Status::kUnbounded;
      break;
    case 2:
      sol.status = Status::kInfeasible;
      break;
    case 3:
      sol.status = Status::kInaccurate;
      break;
    default:
      sol.status = Status::kNumericalTrouble;
      break;
  }
  if (code != 0)
    sol.message =
        std::string("CSDP: ") + csdp_code_text(code) + " (code " + std::to_string(code) + ")";
  if (!sol.y_.allFinite() && sol.ok()) {
    sol.status = Status::kNumericalTrouble;
    sol.message = "CSDP returned a non-finite solution";
  }
  // Worst constraint at the returned point.
  double worst = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < p.cons.size(); ++i) {
    Eigen::MatrixXd F = p.cons[i].F0;
    for (const auto& [sv, M] : t.coef[i]) F += sol.y_(sv) * M;
    worst = std::min(worst, min_eig(F) - margin_of(p.cons[i], p.opt));
  }
  sol.min_eigenvalue = worst;
  return sol;
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
