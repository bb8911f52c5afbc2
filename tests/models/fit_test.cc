// tests/models/fit_test.cc — `ncosim fit`'s families (models/fit.h): an EM stopped at its cap is
// not converged and never selected; intervals at the edge of a parameter's range are intervals
// (Clopper–Pearson for the iid families, a likelihood-ratio bound for a hidden chain), never the
// degenerate [x, x]; the information matrix of a large hidden model (many delay values) is
// computed from the score and agrees with the likelihood's Hessian where both can be.
#include "models/fit.h"

#include <gtest/gtest.h>

#include <cmath>

#include "kernel/rng.h"
#include "models/fit_internal.h"
#include "models/link.h"

namespace ncosim::models {
namespace {

std::vector<int> synthesize(Link& link, std::uint64_t seed, int n) {
  kernel::Rng rng = kernel::make_stream(seed, 0, kernel::stream_id(kernel::StreamKind::kLink, 3));
  link.reset(rng);
  std::vector<int> sym;
  for (int i = 0; i < n; ++i) {
    const std::int64_t d = link.transmit(rng);
    sym.push_back(d == kLost ? 0 : static_cast<int>(d) + 1);
  }
  return sym;
}

const FitParameter& param(const FitResult& r, const std::string& name) {
  for (const auto& p : r.params) {
    if (p.name == name) return p;
  }
  for (const auto& p : r.derived) {
    if (p.name == name) return p;
  }
  throw std::runtime_error("no parameter " + name);
}

// Bursty losses: a hidden chain explains them far better than independent packets, so only the
// iteration cap can keep gilbert_elliott from winning.
TEST(Fit, AnEmAtItsCapIsNotConvergedAndNeverSelected) {
  const auto ge = make_gilbert_elliott(0.01, 0.1, 0.01, 0.8);
  auto link = ge->clone();
  const std::vector<int> sym = synthesize(*link, 7, 20000);
  FitOptions capped;
  capped.max_iterations = 3;
  capped.intervals = false;
  const FitResult stopped = fit_family("gilbert_elliott", sym, capped);
  EXPECT_FALSE(stopped.converged);
  EXPECT_EQ(stopped.iteration_cap, 3);
  EXPECT_NE(stopped.note.find("not converged"), std::string::npos) << stopped.note;
  EXPECT_NE(stopped.note.find("cap of 3 iterations"), std::string::npos) << stopped.note;
  const FitResult delay = fit_family("delay", sym, capped);
  ASSERT_LT(stopped.bic, delay.bic);  // it would win on the criterion
  EXPECT_EQ(best_fit({stopped, delay}, "bic"), 1U);
  EXPECT_EQ(best_fit({stopped, delay}, "aic"), 1U);
  EXPECT_EQ(best_fit({stopped}, "bic"), 0U);  // nothing converged: the caller says so
  FitOptions free;
  free.intervals = false;
  const FitResult done = fit_family("gilbert_elliott", sym, free);
  EXPECT_TRUE(done.converged) << done.iterations;
  EXPECT_TRUE(done.note.empty()) << done.note;
  EXPECT_EQ(best_fit({done, delay}, "bic"), 0U);
}

// No loss in 5000 packets: the loss is 0 with the exact interval [0, 1 - 0.025^(1/n)], not
// [0, 0]; every packet lost: [0.025^(1/n), 1].
TEST(Fit, ProbabilitiesAtZeroOrOneGetExactIntervals) {
  const int n = 5000;
  const double edge = 1.0 - std::pow(0.025, 1.0 / n);
  const FitResult none = fit_family("bernoulli", std::vector<int>(n, 1), FitOptions{});
  const FitParameter& loss = param(none, "loss");
  EXPECT_EQ(loss.estimate, 0.0);
  EXPECT_EQ(loss.ci_low, 0.0);
  EXPECT_NEAR(loss.ci_high, edge, 1e-9);
  EXPECT_EQ(loss.interval, "clopper_pearson");
  const FitResult all = fit_family("delay", std::vector<int>(n, 0), FitOptions{});
  EXPECT_NEAR(param(all, "loss").ci_low, 1.0 - edge, 1e-9);
  EXPECT_EQ(param(all, "loss").ci_high, 1.0);
  // A delay law with an empty bin inside it.
  std::vector<int> gap;
  for (int i = 0; i < n; ++i) gap.push_back(i % 3 == 0 ? 3 : 1);  // delays 0 and 2, never 1
  const FitResult law = fit_family("delay", gap, FitOptions{});
  EXPECT_EQ(param(law, "pmf[1]").estimate, 0.0);
  EXPECT_NEAR(param(law, "pmf[1]").ci_high, edge, 1e-9);
}

// A hidden chain's probability at 0: a likelihood-ratio bound [0, u] where the log-likelihood
// has fallen by chi-square(1, 95 %) / 2 = 1.92, not the Wald [0, 0].
TEST(Fit, AHiddenProbabilityAtZeroGetsALikelihoodRatioBound) {
  FateHmm h;
  h.transition.resize(2, 2);
  h.transition << 0.95, 0.05, 0.2, 0.8;
  h.emission.resize(2, 2);
  h.emission << 0.0, 1.0, 0.7, 0.3;  // the good state never loses
  auto link = std::make_unique<MarkovLink>(h.transition, std::vector<double>{0.0, 0.7},
                                           std::vector<std::vector<double>>{{1.0}, {1.0}});
  const std::vector<int> sym = synthesize(*link, 11, 20000);
  FitParameter p;
  p.name = "loss_good";
  fit_detail::likelihood_ratio_interval(p, h, true, 0, 0, sym);
  EXPECT_EQ(p.interval, "likelihood_ratio");
  EXPECT_EQ(p.ci_low, 0.0);
  ASSERT_GT(p.ci_high, 0.0);
  EXPECT_LT(p.ci_high, 0.05);
  FateHmm at = h;
  at.emission(0, 0) += p.ci_high;
  at.emission(0, 1) -= p.ci_high;
  EXPECT_NEAR(hmm_loglik(h, sym) - hmm_loglik(at, sym), 0.5 * 3.841458821, 1e-3);
}

// Many delay values (28 here): more free probabilities than the likelihood's Hessian is
// differenced for. Every interval of markov2 is computed (from the score) and none is
// degenerate: the fit printed `transition[0][0] 0.993607 [0.993607, 0.993607]` before.
TEST(Fit, ALargeHiddenModelHasIntervalsThatAreNotDegenerate) {
  Eigen::MatrixXd T(2, 2);
  T << 0.98, 0.02, 0.1, 0.9;
  std::vector<double> fast(14, 0.0), slow(28, 1.0 / 28.0);
  fast[0] = 0.6, fast[1] = 0.3;
  for (std::size_t d = 2; d < fast.size(); ++d) fast[d] = 0.1 / 12.0;
  MarkovLink link(T, {0.02, 0.3}, {fast, slow});
  const std::vector<int> sym = synthesize(link, 5, 60000);
  const FitResult r = fit_family("markov2", sym, FitOptions{});
  ASSERT_TRUE(r.converged);
  ASSERT_GT(fit_detail::free_coordinates(r.model).entries.size(), 30U);
  int finite = 0;
  for (const auto& p : r.params) {
    if (!std::isfinite(p.ci_low)) {
      EXPECT_FALSE(p.note.empty()) << p.name;
      continue;
    }
    ++finite;
    EXPECT_LT(p.ci_low, p.ci_high) << p.name << " " << p.estimate;
    EXPECT_LE(p.ci_low, p.estimate) << p.name;
    EXPECT_GE(p.ci_high, p.estimate) << p.name;
  }
  EXPECT_EQ(finite, static_cast<int>(r.params.size()));
  const FitParameter& stay = param(r, "transition[0][0]");
  EXPECT_LT(stay.ci_low, 0.98);
  EXPECT_GT(stay.ci_high, 0.98);
}

// Where both can be computed (few coordinates), the score's Hessian and the likelihood's give
// the same standard errors (the score leaves out the start's O(1) share of O(N)).
TEST(Fit, TheScoreHessianAgreesWithTheLikelihoodHessian) {
  Eigen::MatrixXd T(2, 2);
  T << 0.97, 0.03, 0.08, 0.92;
  MarkovLink link(T, {0.03, 0.5}, {{0.8, 0.2}, {0.3, 0.7}});
  const std::vector<int> sym = synthesize(link, 3, 50000);
  FitOptions o;
  o.intervals = false;
  const FitResult r = fit_family("markov2", sym, o);
  const auto c = fit_detail::free_coordinates(r.model);
  const Eigen::MatrixXd a = fit_detail::covariance(r.model, c, sym);
  const Eigen::MatrixXd b = fit_detail::covariance_from_scores(r.model, c, sym);
  ASSERT_EQ(a.rows(), b.rows());
  ASSERT_GT(a.rows(), 0);
  for (Eigen::Index k = 0; k < a.rows(); ++k)
    EXPECT_NEAR(std::sqrt(b(k, k)) / std::sqrt(a(k, k)), 1.0, 0.02) << k;
}

}  // namespace
}  // namespace ncosim::models
