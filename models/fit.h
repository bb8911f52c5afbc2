// models/fit.h — maximum-likelihood channel models from a packet trace (`ncosim fit`).
// A trace is the sequence of packet fates of one sender: lost, or delivered after d whole
// periods. Families (each fitted by maximum likelihood):
//   bernoulli        independent losses, one fixed delay (only when every delivered packet has
//                    the same delay); 1 parameter.
//   delay            independent packets, delay d with probability pmf[d], lost otherwise;
//                    one parameter per observed outcome but one.
//   gilbert_elliott  hidden two-state Markov chain stepped per packet, loss probability in each
//                    state (both free), delays independent of the state (their empirical law);
//                    fitted by Baum–Welch (EM, SQUAREM-accelerated) from several starts.
//   markov<K>        hidden K-state chain, per-state loss and per-state delay pmf (Baum–Welch).
// For each: log-likelihood, parameter count k, AIC = 2k - 2 LL, BIC = k ln N - 2 LL, 95 %
// intervals (FitParameter::interval says how each was computed: Clopper–Pearson for the iid
// families' probabilities, exact at 0 and 1; Wald from the observed information of the hidden
// families, a numerical Hessian of the exact log-likelihood, or of its score when the model has
// many free probabilities; a likelihood-ratio bound for a probability the fit puts at 0 or 1),
// and goodness of fit: the loss-run length distribution and the loss indicator's
// autocorrelation, model against trace. An EM that reaches its iteration cap leaves the family
// marked not converged: best_fit() does not select it.
#pragma once

#include <Eigen/Dense>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace ncosim::models {

// A hidden Markov model of the packet fates with symbols 0 = lost, 1 + d = delay d.
struct FateHmm {
  Eigen::MatrixXd transition;  // K x K, per packet
  Eigen::MatrixXd emission;    // K x M, rows sum to 1
  Eigen::VectorXd stationary() const;
};

struct FitParameter {
  std::string name;  // e.g. "p_good_to_bad", "loss[1]", "delay_pmf[0][2]"
  double estimate = 0.0;
  double ci_low = 0.0, ci_high = 0.0;  // 95 %, within the parameter's range; NaN: none
  // How the interval was computed: "clopper_pearson", "wald", "likelihood_ratio" (a bound for an
  // estimate at the edge of its range, the other parameters held at their estimates), "normal"
  // (a mean delay: the sample mean's normal interval), or "" with `note` saying why there is none.
  std::string interval;
  std::string note;
  // Whether `ncosim fit` prints it by default (the long per-delay laws are summarised; every
  // parameter is in fit.json and fit.csv).
  bool summary = true;
};

struct FitResult {
  std::string family;  // bernoulli | delay | gilbert_elliott | markov<K>
  int states = 1;
  FateHmm model;  // the fitted law of the fates (iid families: one state)
  double loglik = 0.0;
  int parameters = 0;
  double aic = 0.0, bic = 0.0;
  int iterations = 0;     // EM iterations of the best start (0: closed form)
  int iteration_cap = 0;  // the EM's cap (FitOptions::max_iterations; 0: closed form)
  int starts = 0;
  bool converged = true;  // false: the EM stopped at its cap (see `note`)
  std::string note;       // why the family is not converged, or its intervals are partial
  std::vector<FitParameter> params;
  // Quantities a user reads, derived from `params`: gilbert_elliott's stationary loss probability
  // (`mean_loss`) and mean loss-run length (`mean_burst`), the keys by which a [[link]] of kind
  // gilbert_elliott is written (Wald intervals by the delta method on the same covariance as
  // `params`; mean_burst in [1, inf)); every family's mean delay of a delivered packet
  // (`mean_delay`, per state `mean_delay[i]` for markov<K>).
  std::vector<FitParameter> derived;
  // The marginal law of the fates: P(delay = d), d = 0 .. the longest delay seen (the rest lost),
  // under the fitted model's stationary law: what a design assumes of the link (design_pmf).
  std::vector<double> marginal_pmf() const;
  std::string link_toml;  // a [[link]] table reproducing the fitted model
  // Goodness of fit: P(loss run = L), L = 1..burst_observed.size(), and the autocorrelation
  // of the loss indicator at lags 1..acf_observed.size(), observed and under the model.
  std::vector<double> burst_observed, burst_model, acf_observed, acf_model;
  double burst_tv = 0.0;  // total variation distance between the two run-length laws
  double acf_rmse = 0.0;  // root mean square difference of the autocorrelations
};

struct FitOptions {
  std::vector<std::string> families{"bernoulli", "delay", "gilbert_elliott", "markov2", "markov3"};
  int starts = 4;  // EM starts per hidden family
  int max_iterations = 2000;
  double tolerance = 1e-9;  // stop when an EM step raises LL by less than tolerance * N
  int acf_lags = 20;
  bool intervals = true;
  std::string link_name = "fitted";
};

// The largest delay (periods) the families hold: their laws are dense in the delay (a K x
// (delay + 2) emission matrix), so a longer delay is refused before anything is allocated.
constexpr std::int64_t kMaxFitDelay = 1'000'000;

// Symbols of a trace (0 = lost, 1 + d = delay d). Throws std::out_of_range for a delay above
// kMaxFitDelay (callers check first to name the trace line).
std::vector<int> fate_symbols(const std::vector<std::optional<std::int64_t>>& trace);

// The exact log-likelihood of `symbols` under `hmm` started from its stationary law
// (scaled forward recursion).
double hmm_loglik(const FateHmm& hmm, const std::vector<int>& symbols);

// A fit family as declared in models/fit_families.cc (`ncosim list` prints them).
struct FitFamily {
  std::string name;       // bernoulli | delay | gilbert_elliott | markov2 .. markov8
  std::string help;       // one line
  int states = 1;         // hidden states (1: iid)
  std::string link_kind;  // the [[link]] kind it writes
};
const std::vector<FitFamily>& fit_families();

// Fits one family (names as above). Throws std::invalid_argument for an unknown family and
// when the trace has fewer packets than the family has parameters.
FitResult fit_family(const std::string& family, const std::vector<int>& symbols,
                     const FitOptions& options);

// The number of hidden states of a family name (1 for bernoulli and delay), 0 when unknown.
int family_states(const std::string& family);

// Index of the converged result with the smallest criterion ("bic" or "aic"); when no result
// converged, of the smallest among all (the caller says so).
std::size_t best_fit(const std::vector<FitResult>& fits, const std::string& criterion);

}  // namespace ncosim::models
