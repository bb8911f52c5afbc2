// lmi/csdp.cc — the translation of a Problem to CSDP's semidefinite program, the solve and
// the reading of its result (see lmi.h).
#include <sys/mman.h>
#include <unistd.h>

#include <Eigen/Eigenvalues>
#include <Eigen/SparseCore>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <iomanip>
#include <limits>
#include <map>
#include <mutex>
#include <numeric>
#include <sstream>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "lmi/limits.h"
#include "lmi/lmi.h"
#include "lmi/problem_impl.h"

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

extern "C" void initparams(struct paramstruc* params, int* pprintlevel) {
  *params = g_params;
  *pprintlevel = g_printlevel;
}

namespace ncosim::lmi {

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

// One solver variable per class of raw scalars made equal by Problem::equal().
void number_solver_variables(Problem::Impl& p, Translation& t) {
  t.solver_of.assign(p.nraw, -1);
  std::vector<int> rep_solver(p.nraw, -1);
  for (int r = 0; r < p.nraw; ++r) {
    const int root = p.find(r);
    if (rep_solver[root] < 0) rep_solver[root] = t.k++;
    t.solver_of[r] = rep_solver[root];
  }
}

// Each constraint's coefficients per solver variable (aliases summed, zeros dropped), the solver
// variables used marked, and the constraint sorted into matrix, scalar or constant. False (and
// t.error) for an empty constraint.
bool collect_coefficients(const Problem::Impl& p, Translation& t, std::vector<bool>& used) {
  t.coef.resize(p.cons.size());
  used.assign(t.k, false);
  for (std::size_t i = 0; i < p.cons.size(); ++i) {
    const auto& c = p.cons[i];
    if (c.F0.rows() == 0) {
      t.error = c.name + " is empty (0x0)";
      return false;
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
  return true;
}

// CSDP multiplies the data with each other and with its iterates; beyond kMaxDataMagnitude
// those products overflow, and CSDP 6.2 can then loop without end instead of reporting
// NaN or Inf (found by the structured fuzzer: a plant Bw entry of 1e200 in a sod_jump design).
// The error of the first constraint (or the objective) beyond it, empty when none is.
std::string data_too_large(const Problem::Impl& p, const Translation& t) {
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
    if (m > kMaxDataMagnitude) return too_large(p.cons[i].name, m);
  }
  if (p.has_objective && p.c.size() > 0 && p.c.cwiseAbs().maxCoeff() > kMaxDataMagnitude)
    return too_large("the objective", p.c.cwiseAbs().maxCoeff());
  return {};
}

// The SDP's sizes: the matrix blocks in constraint order, then the diagonal block (if any).
SdpSize sdp_size(const Problem::Impl& p, const Translation& t) {
  SdpSize size;
  size.variables = t.k;
  for (int i : t.matrix_cons) size.block_sizes.push_back(static_cast<int>(p.cons[i].F0.rows()));
  if (!t.scalar_cons.empty()) {
    size.block_sizes.push_back(static_cast<int>(t.scalar_cons.size()));
    size.diagonal_block = true;
  }
  size.blocks = static_cast<int>(size.block_sizes.size());
  size.total_dimension = std::accumulate(size.block_sizes.begin(), size.block_sizes.end(), 0);
  return size;
}

Translation translate(Problem::Impl& p) {
  Translation t;
  if (p.vars.empty()) {
    t.error = "the problem has no variables";
    return t;
  }
  number_solver_variables(p, t);
  std::vector<bool> used;
  if (!collect_coefficients(p, t, used)) return t;
  if (t.matrix_cons.empty() && t.scalar_cons.empty()) {
    t.error = "no constraint involves a variable";
    return t;
  }
  t.error = data_too_large(p, t);
  if (!t.error.empty()) return t;
  for (int r = 0; r < p.nraw; ++r)
    if (!used[t.solver_of[r]]) {
      t.error = "variable " + p.describe(r) +
                " appears in no constraint (CSDP would exit on it; constrain or remove it)";
      return t;
    }
  t.size = sdp_size(p, t);
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

// The first variable-free constraint that does not hold, nullptr when all do: decided here
// (CSDP would see an empty block).
const Expanded* failing_constant_constraint(const Problem::Impl& p, const Translation& t) {
  for (int i : t.constant_cons) {
    const auto& c = p.cons[i];
    if (min_eig(c.F0) < margin_of(c, p.opt) - 1e-12 * std::max(1.0, c.F0.cwiseAbs().maxCoeff()))
      return &c;
  }
  return nullptr;
}

// CSDP's data (malloc'd, 1-based: free_prob releases it): max a'y s.t. C - sum_i y_i A_i >= 0,
// with C = -F0 + margin I per constraint and A_i the coefficients of solver variable i.
struct CsdpData {
  blockmatrix C{};
  double* a = nullptr;
  constraintmatrix* cons = nullptr;
};

// C: one dense block per matrix constraint, then the diagonal block of the scalar ones.
blockmatrix constant_blocks(const Problem::Impl& p, const Translation& t) {
  const int nblocks = t.size.blocks;
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
  return C;
}

// a: the objective per solver variable (aliases summed).
double* objective_vector(const Problem::Impl& p, const Translation& t) {
  Eigen::VectorXd a = Eigen::VectorXd::Zero(t.k);
  if (p.has_objective) {
    for (int r = 0; r < p.c.size(); ++r) a(t.solver_of[r]) += p.c(r);
  }
  double* ca = c_alloc<double>(t.k + 1);
  for (int i = 0; i < t.k; ++i) ca[i + 1] = a(i);
  return ca;
}

// The upper-triangle entries (1-based i, j, value) of one variable's coefficient in one block.
using BlockEntries = std::vector<std::tuple<int, int, double>>;

// Per solver variable, its blocks in increasing block order with their entries.
std::vector<std::vector<std::pair<int, BlockEntries>>> entries_per_variable(const Translation& t) {
  const int k = t.k, nblocks = t.size.blocks;
  std::vector<std::vector<std::pair<int, BlockEntries>>> per_var(k);
  for (std::size_t b = 0; b < t.matrix_cons.size(); ++b)
    for (const auto& [s, M] : t.coef[t.matrix_cons[b]]) {
      BlockEntries ent;
      for (int o = 0; o < M.outerSize(); ++o)
        for (Sparse::InnerIterator it(M, o); it; ++it)
          if (it.row() <= it.col() && it.value() != 0.0)
            ent.emplace_back(static_cast<int>(it.row()) + 1, static_cast<int>(it.col()) + 1,
                             it.value());
      if (!ent.empty()) per_var[s].emplace_back(static_cast<int>(b) + 1, std::move(ent));
    }
  if (t.size.diagonal_block) {
    std::vector<BlockEntries> diag(k);
    for (std::size_t i = 0; i < t.scalar_cons.size(); ++i)
      for (const auto& [s, M] : t.coef[t.scalar_cons[i]])
        diag[s].emplace_back(static_cast<int>(i) + 1, static_cast<int>(i) + 1, M.coeff(0, 0));
    for (int s = 0; s < k; ++s)
      if (!diag[s].empty()) per_var[s].emplace_back(nblocks, std::move(diag[s]));
  }
  return per_var;
}

// A_1 .. A_k: per solver variable, a linked list of sparse blocks in increasing block order
// (prepended in reverse).
constraintmatrix* constraint_matrices(const Translation& t, const blockmatrix& C) {
  const auto per_var = entries_per_variable(t);
  constraintmatrix* cons = c_alloc<constraintmatrix>(t.k + 1);
  for (int s = 0; s < t.k; ++s) {
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
  return cons;
}

paramstruc csdp_parameters(const Options& opt) {
  paramstruc prm{};
  prm.axtol = prm.atytol = prm.objtol = opt.tolerance;
  prm.pinftol = 1e8;
  prm.dinftol = 1e8;
  prm.maxiter = opt.max_iterations;
  prm.minstepfrac = 0.90;
  prm.maxstepfrac = 0.97;
  prm.minstepp = 1e-8;
  prm.minstepd = 1e-8;
  prm.usexzgap = 1;
  prm.tweakgap = 0;
  prm.affine = 0;
  prm.perturbobj = 1.0;
  prm.fastmode = 0;
  return prm;
}

// What one CSDP call returned.
struct CsdpResult {
  int code = -1;
  double pobj = 0.0, dobj = 0.0;
  Eigen::VectorXd y;  // per solver variable
  double seconds = 0.0;
  std::string log;
};

// CSDP on the data (one call at a time: its parameters and the exit hook are process-wide);
// the data are released.
CsdpResult run_csdp(const Options& opt, const SdpSize& size, int k, CsdpData d) {
  CsdpResult r;
  blockmatrix X{}, Z{};
  double* y = nullptr;
  {
    std::lock_guard<std::mutex> lock(csdp_mutex());
    g_params = csdp_parameters(opt);
    g_printlevel = opt.verbose ? 1 : 0;
    StdoutCapture capture;
    const auto t0 = std::chrono::steady_clock::now();
    static const bool exit_hook = std::atexit(exit_during_csdp) == 0;
    (void)exit_hook;
    g_in_csdp.store(true);
    initsoln(size.total_dimension, k, d.C, d.a, d.cons, &X, &y, &Z);
    r.code = easy_sdp(size.total_dimension, k, d.C, d.a, d.cons, 0.0, &X, &y, &Z, &r.pobj, &r.dobj);
    g_in_csdp.store(false);
    r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    r.log = capture.finish();
  }
  r.y.resize(k);
  for (int i = 0; i < k; ++i) r.y(i) = y[i + 1];
  free_prob(size.total_dimension, k, d.C, d.a, d.cons, X, y, Z);
  return r;
}

Status status_of(int csdp_code) {
  switch (csdp_code) {
    case 0:
      return Status::kOptimal;
    case 1:
      return Status::kUnbounded;
    case 2:
      return Status::kInfeasible;
    case 3:
      return Status::kInaccurate;
    default:
      return Status::kNumericalTrouble;
  }
}

// min over constraints of lambda_min(F(y)) - margin: the worst constraint at the point y.
double worst_constraint(const Problem::Impl& p, const Translation& t, const Eigen::VectorXd& y) {
  double worst = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < p.cons.size(); ++i) {
    Eigen::MatrixXd F = p.cons[i].F0;
    for (const auto& [sv, M] : t.coef[i]) F += y(sv) * M;
    worst = std::min(worst, min_eig(F) - margin_of(p.cons[i], p.opt));
  }
  return worst;
}
}  // namespace

SdpSize Problem::size() const { return translate(*impl_).size; }

Solution Problem::solve() const {
  Impl& p = *impl_;
  p.check_resources();
  observe_solve(p);
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
  if (const Expanded* c = failing_constant_constraint(p, t)) {
    sol.status = Status::kInfeasible;
    sol.message = c->name + " involves no variable and does not hold";
    return sol;
  }
  CsdpData d;
  d.C = constant_blocks(p, t);
  d.a = objective_vector(p, t);
  d.cons = constraint_matrices(t, d.C);
  CsdpResult r = run_csdp(p.opt, t.size, t.k, d);
  sol.seconds = r.seconds;
  sol.log = std::move(r.log);
  sol.y_ = std::move(r.y);

  const int code = r.code;
  sol.csdp_code = code;
  const double s = p.objective_sign;
  sol.primal_objective = s * (r.pobj + p.c0);
  sol.dual_objective = s * (r.dobj + p.c0);
  sol.objective = s * (0.5 * (r.pobj + r.dobj) + p.c0);
  if (!p.has_objective) sol.objective = sol.primal_objective = sol.dual_objective = 0.0;
  sol.status = status_of(code);
  if (code != 0)
    sol.message =
        std::string("CSDP: ") + csdp_code_text(code) + " (code " + std::to_string(code) + ")";
  if (!sol.y_.allFinite() && sol.ok()) {
    sol.status = Status::kNumericalTrouble;
    sol.message = "CSDP returned a non-finite solution";
  }
  sol.min_eigenvalue = worst_constraint(p, t, sol.y_);
  return sol;
}

}  // namespace ncosim::lmi
