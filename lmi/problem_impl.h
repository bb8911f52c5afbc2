// lmi/problem_impl.h — the inside of an lmi::Problem, shared by lmi.cc (building),
// limits.cc (resource estimates) and csdp.cc (the translation to CSDP and the solve).
// Not part of the interface: only the lmi/ sources include it.
#pragma once

#include <Eigen/SparseCore>
#include <algorithm>
#include <cmath>
#include <map>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "lmi/limits.h"
#include "lmi/lmi.h"

namespace ncosim::lmi {

using Sparse = Eigen::SparseMatrix<double>;

// max |M - M'| of a sparse matrix (0 for an empty one).
inline double asymmetry(const Sparse& M) {
  Sparse D = M - Sparse(M.transpose());
  double m = 0.0;
  for (int k = 0; k < D.outerSize(); ++k)
    for (Sparse::InnerIterator it(D, k); it; ++it) m = std::max(m, std::abs(it.value()));
  return m;
}
// Above this magnitude, problem data are refused (translate()).
constexpr double kMaxDataMagnitude = 1e100;

inline double max_abs(const Sparse& M) {
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

// Calls the solve observer of this thread (ScopedSolveObserver), if any, with p's estimate.
void observe_solve(const Problem::Impl& p);

}  // namespace ncosim::lmi
