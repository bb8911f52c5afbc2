// tests/lmi: the LMI layer on CSDP — known optima, every failure status, and CSDP's quirks
// (not reentrant, exit() on malformed input, stdout chatter, ./param.csdp).
#include "lmi/lmi.h"

#include <gtest/gtest.h>
#include <sys/mman.h>
#include <unistd.h>

#include <Eigen/Eigenvalues>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <thread>

namespace ncosim::lmi {
namespace {

using Eigen::MatrixXd;

MatrixXd StableA() {
  MatrixXd A(3, 3);
  A << 0.5, 0.4, 0.0, -0.3, 0.6, 0.2, 0.1, 0.0, 0.7;
  return A;
}

double MaxEig(const MatrixXd& M) {
  return Eigen::SelfAdjointEigenSolver<MatrixXd>(0.5 * (M + M.transpose()))
      .eigenvalues()
      .maxCoeff();
}

// Solution of P = A' P A + Q by fixed-point iteration (A Schur stable).
MatrixXd Lyapunov(const MatrixXd& A, const MatrixXd& Q) {
  MatrixXd P = Q;
  for (int i = 0; i < 10000; ++i) {
    MatrixXd next = A.transpose() * P * A + Q;
    if ((next - P).norm() < 1e-15 * P.norm()) return next;
    P = next;
  }
  return P;
}

// Stabilising DARE solution X = A'XA - A'XB (R + B'XB)^-1 B'XA + Q by value iteration from 0.
MatrixXd Dare(const MatrixXd& A, const MatrixXd& B, const MatrixXd& Q, const MatrixXd& R) {
  MatrixXd X = MatrixXd::Zero(A.rows(), A.cols());
  for (int i = 0; i < 100000; ++i) {
    MatrixXd next =
        A.transpose() * X * A -
        A.transpose() * X * B * (R + B.transpose() * X * B).ldlt().solve(B.transpose() * X * A) + Q;
    if ((next - X).norm() < 1e-14 * next.norm()) return next;
    X = next;
  }
  return X;
}

TEST(Lmi, LyapunovInequalityIsFeasibleAndMinTraceIsTheLyapunovSolution) {
  const MatrixXd A = StableA();
  const MatrixXd I = MatrixXd::Identity(3, 3);
  Problem prob;
  Var P = prob.symmetric(3, "P");
  prob.add(A.transpose() * P * A - P + I <= 0);
  prob.add(P > 0);
  prob.minimize(trace(P));
  const Solution s = prob.solve();
  ASSERT_EQ(s.status, Status::kOptimal) << s.message;
  const MatrixXd Pv = s.value(P);
  EXPECT_LT(MaxEig(A.transpose() * Pv * A - Pv), 0.0);
  // Any feasible P dominates the Lyapunov solution, which is feasible: it is the minimiser.
  const MatrixXd Pstar = Lyapunov(A, I);
  EXPECT_NEAR(s.objective, Pstar.trace(), 1e-6 * Pstar.trace());
  EXPECT_LT((Pv - Pstar).norm(), 1e-5 * Pstar.norm());
  EXPECT_NEAR(s.value(trace(P)), s.objective, 1e-6 * Pstar.trace());
  EXPECT_EQ(s.size.variables, 6);
  EXPECT_GE(s.min_eigenvalue, -1e-7);
}

TEST(Lmi, FeasibilityWithoutObjective) {
  const MatrixXd A = StableA();
  Problem prob;
  Var P = prob.symmetric(3, "P");
  prob.add(lmi(A.transpose() * P * A - P < 0, 1e-3));
  prob.add(P >= MatrixXd::Identity(3, 3));
  const Solution s = prob.solve();
  ASSERT_TRUE(s.ok()) << s.message;
  const MatrixXd Pv = s.value(P);
  EXPECT_LT(MaxEig(A.transpose() * Pv * A - Pv), -1e-3 + 1e-7);
  EXPECT_GT(-MaxEig(-Pv), 1.0 - 1e-7);
}

TEST(Lmi, RiccatiInequalityMaxTraceIsTheDareSolution) {
  MatrixXd A(3, 3), B(3, 1), Q = MatrixXd::Identity(3, 3), R = MatrixXd::Identity(1, 1);
  A << 1.1, 0.3, 0.0, 0.0, 0.9, 0.5, 0.2, 0.0, 0.8;  // unstable
  B << 0.0, 0.5, 1.0;
  const MatrixXd Xstar = Dare(A, B, Q, R);
  for (bool via_minimize : {false, true}) {
    Problem prob;
    Var X = prob.symmetric(3, "X");
    prob.add(block({{A.transpose() * X * A - X + Q, A.transpose() * X * B},
                    {B.transpose() * X * A, R + B.transpose() * X * B}}) >= 0);
    if (via_minimize)
      prob.minimize(-1.0 * trace(X));
    else
      prob.maximize(trace(X));
    const Solution s = prob.solve();
    ASSERT_TRUE(s.ok()) << s.message;
    const double expect = via_minimize ? -Xstar.trace() : Xstar.trace();
    EXPECT_NEAR(s.objective, expect, 1e-6 * Xstar.trace());
    EXPECT_LT((s.value(X) - Xstar).norm(), 1e-5 * Xstar.norm()) << s.value(X) << "\n\n" << Xstar;
  }
}

TEST(Lmi, FullVariablesTransposesAndEqualities) {
  // Find a gain K with A + B K Schur stable: [[P, (A+BK)'P],[P(A+BK), P]] > 0 is bilinear; the
  // standard change Y = K P' gives [[W, (AW + BY)'], [AW + BY, W]] > 0 with W = P^-1.
  MatrixXd A(2, 2), B(2, 1);
  A << 1.2, 1.0, 0.0, 0.9;
  B << 0.0, 1.0;
  Problem prob;
  Var W = prob.symmetric(2, "W");
  Var Y = prob.full(1, 2, "Y");
  Var W2 = prob.symmetric(2, "W2");
  prob.equal(W, W2);
  Expr AWBY = A * W2 + B * Y;
  prob.add(lmi(block({{W, AWBY.transpose()}, {AWBY, W}}) > 0, 1e-4, "stability"));
  prob.add(W <= 10.0 * MatrixXd::Identity(2, 2));
  const Solution s = prob.solve();
  ASSERT_TRUE(s.ok()) << s.message;
  EXPECT_EQ(s.size.variables, 3 + 2);  // W2 aliased to W
  EXPECT_EQ(s.value(W), s.value(W2));
  const MatrixXd K = s.value(Y) * s.value(W).inverse();
  Eigen::EigenSolver<MatrixXd> es(A + B * K);
  EXPECT_LT(es.eigenvalues().cwiseAbs().maxCoeff(), 1.0);
  const MatrixXd blk = s.value(block({{W, AWBY.transpose()}, {AWBY, W}}));
  EXPECT_LT((blk - blk.transpose()).norm(), 1e-12);
}

TEST(Lmi, ScalarConstraintsShareADiagonalBlock) {
  Problem prob;
  Var x = prob.full(1, 1, "x");
  Var y = prob.full(1, 1, "y");
  const MatrixXd one = MatrixXd::Ones(1, 1);
  prob.add(Expr(x) >= one);
  prob.add(Expr(y) >= 2.0 * one);
  prob.add(Expr(x) + Expr(y) <= 10.0 * one);
  prob.minimize(entry(x, 0, 0) + 3.0 * entry(y, 0, 0));
  const Solution s = prob.solve();
  ASSERT_EQ(s.status, Status::kOptimal) << s.message;
  EXPECT_NEAR(s.objective, 7.0, 1e-6);
  EXPECT_EQ(s.size.blocks, 1);
  EXPECT_TRUE(s.size.diagonal_block);
  EXPECT_EQ(s.size.block_sizes, std::vector<int>{3});
}

TEST(Lmi, InfeasibleProblemsReportInfeasible) {
  {
    Problem prob;  // x >= 1 and x <= -1
    Var x = prob.full(1, 1, "x");
    prob.add(Expr(x) >= MatrixXd::Ones(1, 1));
    prob.add(Expr(x) <= -MatrixXd::Ones(1, 1));
    prob.minimize(entry(x, 0, 0));
    const Solution s = prob.solve();
    EXPECT_EQ(s.status, Status::kInfeasible) << s.message;
    EXPECT_EQ(s.csdp_code, 2);
    EXPECT_FALSE(s.ok());
  }
  {
    Problem prob;  // P >= I and A'PA - P >= 0 with A Schur stable
    const MatrixXd A = StableA();
    Var P = prob.symmetric(3, "P");
    prob.add(P >= MatrixXd::Identity(3, 3));
    prob.add(A.transpose() * P * A - P >= 0);
    prob.minimize(trace(P));
    const Solution s = prob.solve();
    EXPECT_EQ(s.status, Status::kInfeasible) << s.message;
    EXPECT_STREQ(to_string(s.status), "infeasible");
  }
  {
    Problem prob;  // a violated constant LMI never reaches CSDP
    Var P = prob.symmetric(2, "P");
    prob.add(P >= 0);
    prob.add(Expr(-MatrixXd::Identity(2, 2)) >= 0);
    const Solution s = prob.solve();
    EXPECT_EQ(s.status, Status::kInfeasible);
    EXPECT_EQ(s.csdp_code, -1);
  }
}

TEST(Lmi, UnboundedProblemReportsUnbounded) {
  Problem prob;
  Var P = prob.symmetric(2, "P");
  prob.add(P <= MatrixXd::Identity(2, 2));
  prob.minimize(trace(P));
  const Solution s = prob.solve();
  EXPECT_EQ(s.status, Status::kUnbounded) << s.message;
  EXPECT_EQ(s.csdp_code, 1);
}

TEST(Lmi, MalformedProblemsAreAnErrorStatusNotAnExit) {
  {
    Problem prob;  // an unused variable (CSDP would exit)
    Var P = prob.symmetric(2, "P");
    Var Q = prob.symmetric(2, "Q");
    prob.add(P >= 0);
    prob.minimize(trace(P) + trace(Q));
    const Solution s = prob.solve();
    EXPECT_EQ(s.status, Status::kInvalidProblem);
    EXPECT_NE(s.message.find("'Q'"), std::string::npos) << s.message;
    EXPECT_EQ(s.csdp_code, -1);
  }
  {
    Problem prob;  // a variable whose coefficients cancel
    Var P = prob.symmetric(2, "P");
    Var Q = prob.symmetric(2, "Q");
    prob.add(Expr(P) + Expr(Q) - Expr(Q) >= 0);
    const Solution s = prob.solve();
    EXPECT_EQ(s.status, Status::kInvalidProblem);
    EXPECT_NE(s.message.find("'Q'"), std::string::npos) << s.message;
  }
  {
    Problem prob;  // one entry of a variable unused: only the diagonal of P is constrained
    Var P = prob.symmetric(2, "P");
    const MatrixXd e0 = MatrixXd::Identity(2, 2).col(0), e1 = MatrixXd::Identity(2, 2).col(1);
    prob.add(e0.transpose() * P * e0 >= 0);
    prob.add(e1.transpose() * P * e1 >= 0);
    const Solution s = prob.solve();
    EXPECT_EQ(s.status, Status::kInvalidProblem);
    EXPECT_NE(s.message.find("'P' entry (0,1)"), std::string::npos) << s.message;
  }
  {
    Problem prob;  // no variable at all
    EXPECT_EQ(prob.solve().status, Status::kInvalidProblem);
  }
  {
    Problem prob;  // no constraint
    Var P = prob.symmetric(2, "P");
    prob.minimize(trace(P));
    const Solution s = prob.solve();
    EXPECT_EQ(s.status, Status::kInvalidProblem);
    EXPECT_STREQ(to_string(s.status), "invalid_problem");
  }
  {
    Problem prob;  // an empty (0x0) block
    Var P = prob.symmetric(2, "P");
    prob.add(P >= 0);
    prob.add(Expr(MatrixXd(0, 0)) >= 0);
    const Solution s = prob.solve();
    EXPECT_EQ(s.status, Status::kInvalidProblem);
    EXPECT_NE(s.message.find("empty"), std::string::npos) << s.message;
  }
}

// CSDP 6.2 can loop without end on data whose products overflow (found by the structured
// fuzzer: a sod_jump design of a plant with a Bw entry of 1e300, tests/cli/reliability_test.cc);
// data above 1e100 in magnitude are refused before the solver sees them, naming the constraint.
TEST(Lmi, DataBeyondTheSolversRangeAreAnInvalidProblem) {
  MatrixXd A = StableA();
  const MatrixXd I = MatrixXd::Identity(3, 3);
  for (const double big : {1e60, 1e101, 1e150}) {  // A' P A: coefficients up to big^2
    A(0, 1) = big;
    Problem prob;
    Var P = prob.symmetric(3, "P");
    prob.add(lmi(A.transpose() * P * A - P + I <= 0, -1.0, "decay"));
    prob.add(P > 0);
    prob.minimize(trace(P));
    const Solution s = prob.solve();
    EXPECT_EQ(s.status, Status::kInvalidProblem) << big;
    EXPECT_NE(s.message.find("decay has a coefficient of magnitude"), std::string::npos)
        << s.message;
    EXPECT_NE(s.message.find("rescale the model"), std::string::npos) << s.message;
  }
  Problem prob;  // an objective weight beyond the range
  Var P = prob.symmetric(1, "P");
  prob.add(P > 0);
  prob.minimize(1e200 * trace(P));
  const Solution s = prob.solve();
  EXPECT_EQ(s.status, Status::kInvalidProblem);
  EXPECT_NE(s.message.find("the objective has a coefficient"), std::string::npos) << s.message;
}

TEST(Lmi, ExpressionMistakesThrowAtTheirSource) {
  Problem prob;
  Var P = prob.symmetric(2, "P");
  Var L = prob.full(2, 3, "L");
  EXPECT_THROW(Expr(P) + Expr(L), Error);       // size mismatch
  EXPECT_THROW(prob.add(Expr(L) >= 0), Error);  // not square
  MatrixXd A(2, 2);
  A << 1, 2, 3, 4;
  EXPECT_THROW(prob.add(A * P >= 0), Error);                // not symmetric
  EXPECT_THROW(prob.add(Expr(A) + Expr(P) >= 0), Error);    // constant not symmetric
  EXPECT_THROW(block({{P, L}, {L, P}}), Error);             // block shapes
  EXPECT_THROW(MatrixXd::Identity(3, 3) * Expr(P), Error);  // product shapes
  EXPECT_THROW(Expr(P) >= 1.0, Error);                      // compare with 0 only
  EXPECT_THROW(prob.symmetric(0), Error);
  Problem other;
  Var Q = other.symmetric(5, "Q");
  EXPECT_THROW(prob.add(Expr(Q) >= 0), Error);  // foreign variable
  EXPECT_THROW(prob.equal(P, Q), Error);
}

TEST(Lmi, IterationLimitIsNumericalTroubleAndOptionsReachCsdp) {
  const MatrixXd A = StableA();
  Options o;
  o.max_iterations = 1;
  Problem prob(o);
  Var P = prob.symmetric(3, "P");
  prob.add(A.transpose() * P * A - P + MatrixXd::Identity(3, 3) <= 0);
  prob.minimize(trace(P));
  const Solution s = prob.solve();
  EXPECT_EQ(s.status, Status::kNumericalTrouble) << s.message;
  EXPECT_EQ(s.csdp_code, 4);
  EXPECT_STREQ(to_string(s.status), "numerical_trouble");
}

Solution SolveLyapunov(double scale) {
  const MatrixXd A = scale * StableA();
  Problem prob;
  Var P = prob.symmetric(3, "P");
  prob.add(A.transpose() * P * A - P + MatrixXd::Identity(3, 3) <= 0);
  prob.add(P > 0);
  prob.minimize(trace(P));
  return prob.solve();
}

TEST(Lmi, SolvesFromSeveralThreadsAgreeWithSerialSolves) {
  constexpr int kThreads = 4, kEach = 6;
  std::vector<double> serial(kThreads * kEach), parallel(kThreads * kEach);
  for (int i = 0; i < kThreads * kEach; ++i) {
    const Solution s = SolveLyapunov(0.5 + 0.02 * i);
    ASSERT_TRUE(s.ok()) << i << ": " << s.message;
    serial[i] = s.objective;
  }
  std::vector<std::thread> pool;
  for (int t = 0; t < kThreads; ++t)
    pool.emplace_back([t, &parallel] {
      for (int j = 0; j < kEach; ++j) {
        const int i = t * kEach + j;
        const Solution s = SolveLyapunov(0.5 + 0.02 * i);
        parallel[i] = s.ok() ? s.objective : -1.0;
      }
    });
  for (auto& th : pool) th.join();
  for (int i = 0; i < kThreads * kEach; ++i) EXPECT_EQ(parallel[i], serial[i]) << i;
}

// fd 1 redirected into a memory file while the test body runs.
class CaptureFd1 {
 public:
  CaptureFd1() : fd_(memfd_create("test-stdout", 0)), saved_(dup(1)) {
    std::fflush(stdout);
    dup2(fd_, 1);
  }
  long Finish() {
    std::fflush(stdout);
    dup2(saved_, 1);
    close(saved_);
    const long n = lseek(fd_, 0, SEEK_END);
    close(fd_);
    return n;
  }

 private:
  int fd_, saved_;
};

TEST(Lmi, NothingIsPrintedToStdoutAndTheVerboseLogIsKept) {
  Solution quiet, verbose;
  CaptureFd1 cap;
  quiet = SolveLyapunov(1.0);
  {
    const MatrixXd A = StableA();
    Options o;
    o.verbose = true;
    Problem prob(o);
    Var P = prob.symmetric(3, "P");
    prob.add(A.transpose() * P * A - P + MatrixXd::Identity(3, 3) <= 0);
    prob.minimize(trace(P));
    verbose = prob.solve();
  }
  const long written = cap.Finish();
  EXPECT_EQ(written, 0);
  EXPECT_EQ(quiet.status, Status::kOptimal);
  EXPECT_TRUE(quiet.log.empty()) << quiet.log;
  EXPECT_NE(verbose.log.find("Iter"), std::string::npos) << verbose.log;
}

TEST(Lmi, ParamCsdpInTheWorkingDirectoryIsIgnored) {
  namespace fs = std::filesystem;
  const fs::path old = fs::current_path();
  const fs::path dir = fs::temp_directory_path() / ("ncosim-lmi-param-" + std::to_string(getpid()));
  fs::create_directories(dir);
  {
    std::ofstream f(dir / "param.csdp");
    f << "axtol=1.0e-8\natytol=1.0e-8\nobjtol=1.0e-8\npinftol=1.0e8\ndinftol=1.0e8\nmaxiter=1\n"
         "minstepfrac=0.90\nmaxstepfrac=0.97\nminstepp=1.0e-8\nminstepd=1.0e-8\nusexzgap=1\n"
         "tweakgap=0\naffine=0\nprintlevel=3\nperturbobj=1\nfastmode=0\n";
  }
  fs::current_path(dir);
  CaptureFd1 cap;
  const Solution s = SolveLyapunov(1.0);
  const long written = cap.Finish();
  fs::current_path(old);
  fs::remove_all(dir);
  EXPECT_EQ(s.status, Status::kOptimal) << s.message;  // maxiter=1 would make it fail
  EXPECT_EQ(written, 0);
}

}  // namespace
}  // namespace ncosim::lmi
