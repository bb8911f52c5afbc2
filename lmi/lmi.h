// lmi/lmi.h — a small modelling front end for linear matrix inequalities, solved by CSDP.
//
//   lmi::Problem prob;
//   lmi::Var P = prob.symmetric(n, "P");
//   prob.add(lmi::block({{P, A.transpose() * P}, {P * A, P}}) > 0);   // strict: margin
//   prob.add(P >= I);                                                  // expr >= expr
//   prob.minimize(lmi::trace(P));
//   lmi::Solution s = prob.solve();
//   if (s.ok()) use(s.value(P));
//
// Decision variables are the scalar entries of matrix variables (symmetric: the upper
// triangle; full: every entry). An LMI F(y) = F0 + sum y_i F_i >= 0 is CSDP's dual form
// sum y_i A_i - C >= 0 with A_i = F_i, C = -F0, and the objective min c'y is CSDP's a.
// 1x1 constraints share one diagonal block. Problem::equal(X, Y) identifies the entries of
// two variables (the scalar is eliminated, no numerical equality constraint is added).
//
// CSDP quirks hidden here (each has a test in tests/lmi): the solver is not reentrant (one
// process-wide mutex serialises solves); it exits the process on malformed input (every
// problem is validated first, and a malformed one is Status::kInvalidProblem with a
// message); it prints to stdout and reads ./param.csdp (its parameters are set here, its
// output is captured into Solution::log, never written to stdout: while CSDP runs, fd 1 of
// the process points to a memory file, so another thread's stdout output during a solve
// lands in that log too — ncosim writes nothing to stdout from worker threads).
// Expression-building errors (size mismatch, product of a variable with a variable,
// non-square or non-symmetric LMI) throw lmi::Error at the point of the mistake.
#pragma once

#include <Eigen/Dense>
#include <concepts>
#include <initializer_list>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace ncosim::lmi {

class Error : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

enum class Status {
  kOptimal,           // CSDP 0: solved to the requested accuracy
  kInaccurate,        // CSDP 3: partial success, a solution with reduced accuracy
  kInfeasible,        // CSDP 2 (dual infeasible): no y satisfies the LMIs
  kUnbounded,         // CSDP 1 (primal infeasible): the objective is unbounded below
  kNumericalTrouble,  // CSDP 4-10: iteration limit, stuck, singular, NaN/Inf
  kInvalidProblem,    // rejected before CSDP was called (see Solution::message)
};
// "optimal", "inaccurate", "infeasible", "unbounded", "numerical_trouble", "invalid_problem".
const char* to_string(Status s);

class Problem;

// A matrix variable owned by a Problem (a cheap handle).
struct Var {
  int id = -1;
  int rows = 0, cols = 0;
  bool symmetric = false;
  long problem = 0;  // serial number of the owning Problem
};

// An affine matrix expression: constant + sum_t L_t * V_t(') * R_t.
class Expr {
 public:
  Expr() = default;
  Expr(const Eigen::MatrixXd&
           constant);  // NOLINT(google-explicit-constructor): constants mix freely
  Expr(const Var& v);  // NOLINT(google-explicit-constructor)
  template <typename D>
  Expr(const Eigen::MatrixBase<D>& m)
      : Expr(Eigen::MatrixXd(m)) {}  // NOLINT(google-explicit-constructor)

  int rows() const { return static_cast<int>(constant_.rows()); }
  int cols() const { return static_cast<int>(constant_.cols()); }
  Expr transpose() const;
  bool has_variables() const { return !terms_.empty(); }

  Expr& operator+=(const Expr& o);
  Expr& operator-=(const Expr& o);
  Expr& operator*=(double s);

  static Expr lmul(const Eigen::MatrixXd& m, const Expr& e);  // m * e
  static Expr rmul(const Expr& e, const Eigen::MatrixXd& m);  // e * m
  friend Expr block(const std::vector<std::vector<Expr>>& rows);

  struct Term {
    int var;
    long problem;
    bool transposed;
    Eigen::MatrixXd L, R;  // L * V(') * R
  };
  const Eigen::MatrixXd& constant() const { return constant_; }
  const std::vector<Term>& terms() const { return terms_; }

 private:
  Eigen::MatrixXd constant_;
  std::vector<Term> terms_;
};

Expr operator+(Expr a, const Expr& b);
Expr operator-(Expr a, const Expr& b);
Expr operator-(const Expr& a);
Expr operator*(double s, const Expr& e);
inline Expr operator*(const Expr& e, double s) { return s * e; }
template <typename T>
concept ExprLike = std::same_as<T, Expr> || std::same_as<T, Var>;
template <typename D, ExprLike E>
Expr operator*(const Eigen::MatrixBase<D>& m, const E& e) {
  return Expr::lmul(Eigen::MatrixXd(m), Expr(e));
}
template <typename D, ExprLike E>
Expr operator*(const E& e, const Eigen::MatrixBase<D>& m) {
  return Expr::rmul(Expr(e), Eigen::MatrixXd(m));
}
// Block matrix [[E11, E12, ...], [E21, ...]]: heights agree along a row, widths down a column.
Expr block(std::initializer_list<std::initializer_list<Expr>> rows);
Expr block(const std::vector<std::vector<Expr>>& rows);

// A linear scalar function of the decision variables: constant + sum_p sum_ij W_p(i,j) E_p(i,j).
struct LinearForm {
  double constant = 0.0;
  std::vector<std::pair<Expr, Eigen::MatrixXd>> parts;  // (E_p, W_p), W_p the shape of E_p
  LinearForm() = default;
  LinearForm(double c) : constant(c) {}  // NOLINT(google-explicit-constructor)
};
// tr(E) (E square) and E(i, j).
LinearForm trace(const Expr& e);
LinearForm entry(const Expr& e, int i, int j);
LinearForm operator+(LinearForm a, const LinearForm& b);
LinearForm operator-(LinearForm a, const LinearForm& b);
LinearForm operator*(double s, LinearForm f);

// An LMI  expr >= 0 (or > 0 with a margin: expr >= margin * I).
struct Constraint {
  Expr expr;
  bool strict = false;
  double margin = -1.0;  // < 0: Options::strict_margin
  std::string name;
};
Constraint operator>=(const Expr& a, const Expr& b);
Constraint operator<=(const Expr& a, const Expr& b);
Constraint operator>(const Expr& a, const Expr& b);
Constraint operator<(const Expr& a, const Expr& b);
Constraint operator>=(const Expr& a, double zero);  // only 0: `expr >= 0`
Constraint operator>(const Expr& a, double zero);
Constraint operator<=(const Expr& a, double zero);
Constraint operator<(const Expr& a, double zero);
// Explicit form: lmi(expr >= 0), lmi(expr > 0, 1e-6), lmi(expr > 0, 1e-6, "name").
Constraint lmi(Constraint c, double margin = -1.0, std::string name = {});

struct Options {
  double strict_margin = 1e-8;       // default margin of a strict LMI
  int max_iterations = 100;          // CSDP maxiter
  double tolerance = 1e-8;           // CSDP axtol, atytol, objtol
  bool verbose = false;              // CSDP printlevel 1 (log captured in Solution::log)
  double symmetry_tolerance = 1e-9;  // relative asymmetry of an LMI coefficient that is an error
};

// Sizes of the SDP handed to CSDP (for design reports and benchmarks).
struct SdpSize {
  int variables = 0;             // scalar decision variables (CSDP's k)
  int blocks = 0;                // blocks of the block-diagonal X
  std::vector<int> block_sizes;  // matrix blocks, then the diagonal block (if any) last
  bool diagonal_block = false;   // the last block is diagonal (1x1 constraints)
  int total_dimension = 0;       // sum of block sizes (CSDP's n)
};

class Solution {
 public:
  Status status = Status::kInvalidProblem;
  std::string message;     // why it is not optimal (empty when optimal)
  int csdp_code = -1;      // CSDP's return code, -1 when it was not called
  double objective = 0.0;  // primal-dual average of the objective (with its constant)
  double primal_objective = 0.0, dual_objective = 0.0;
  double min_eigenvalue = 0.0;  // min over LMIs of lambda_min(F(y)) - margin (>= ~0 feasible)
  double seconds = 0.0;         // wall time of the CSDP call
  SdpSize size;
  std::string log;  // CSDP's output (printlevel 1 when Options::verbose)

  bool ok() const { return status == Status::kOptimal || status == Status::kInaccurate; }
  Eigen::MatrixXd value(const Var& v) const;
  Eigen::MatrixXd value(const Expr& e) const;
  double value(const LinearForm& f) const;
  const Eigen::VectorXd& y() const { return y_; }

 private:
  friend class Problem;
  Eigen::VectorXd y_;            // per solver variable
  std::vector<int> solver_of_;   // raw scalar -> solver variable
  std::vector<int> var_offset_;  // Var id -> first raw scalar
  std::vector<Var> vars_;
};

class Problem {
 public:
  explicit Problem(Options options = {});
  ~Problem();
  Problem(Problem&&) noexcept;
  Problem& operator=(Problem&&) noexcept;
  Problem(const Problem&) = delete;
  Problem& operator=(const Problem&) = delete;

  Var symmetric(int n, std::string name = {});
  Var full(int rows, int cols, std::string name = {});
  // X == Y entrywise (same shape and kind): Y's entries become X's.
  void equal(const Var& x, const Var& y);
  // Adds an LMI; returns its index. A constant (variable-free) LMI is checked at solve().
  int add(Constraint c);
  void minimize(const LinearForm& f);
  void maximize(const LinearForm& f);
  Options& options();

  SdpSize size() const;  // what solve() would hand to CSDP (validation aside)
  Solution solve() const;

  struct Impl;  // implementation detail (lmi/problem_impl.h)

 private:
  std::unique_ptr<Impl> impl_;
};

}  // namespace ncosim::lmi
