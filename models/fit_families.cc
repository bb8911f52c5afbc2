// models/fit_families.cc — the fit families of `ncosim fit` as declared entries (models/fit.h):
// each names itself, its hidden states, the [[link]] kind it writes, its parameter count and its
// fit; fit_family() looks the name up once (no family is compared by name elsewhere).
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <stdexcept>

#include "models/fit.h"
#include "models/fit_internal.h"

namespace ncosim::models {

using namespace fit_detail;

namespace {

// What every family reads from the trace.
struct TraceSummary {
  explicit TraceSummary(const std::vector<int>& s) : sym(s) {}
  const std::vector<int>& sym;
  double N = 0.0;
  int M = 2, D = 0;  // symbols (lost + delays 0..D); D: the longest delay seen (0 when none)
  std::vector<double> counts;
  double lost = 0.0, delivered = 0.0;
  std::vector<double> q;  // the empirical law of the delivered packets' delays
  double delay_ll = 0.0, loss_ll = 0.0;
  int delay_outcomes = 0;
  double mean_burst = 1.0;
};

TraceSummary summarise(const std::vector<int>& sym) {
  TraceSummary t(sym);
  t.N = static_cast<double>(sym.size());
  t.M = std::max(alphabet(sym), 2);
  t.D = t.M - 2;
  t.counts.assign(static_cast<std::size_t>(t.M), 0.0);
  for (const int s : sym) t.counts[static_cast<std::size_t>(s)] += 1.0;
  t.lost = t.counts[0];
  t.delivered = t.N - t.lost;
  // The delays of the delivered packets: their empirical law and its log-likelihood.
  t.q.assign(static_cast<std::size_t>(t.D + 1), 0.0);
  for (int d = 0; d <= t.D; ++d) {
    const double c = t.counts[static_cast<std::size_t>(d + 1)];
    if (t.delivered > 0.0) t.q[static_cast<std::size_t>(d)] = c / t.delivered;
    if (c > 0.0) {
      t.delay_ll += c * std::log(c / t.delivered);
      ++t.delay_outcomes;
    }
  }
  if (t.delivered == 0.0) t.q[0] = 1.0;
  t.loss_ll = (t.lost > 0.0 ? t.lost * std::log(t.lost / t.N) : 0.0) +
              (t.delivered > 0.0 ? t.delivered * std::log(t.delivered / t.N) : 0.0);
  double run_count = 0.0;
  for (const auto n : loss_runs(sym)) run_count += static_cast<double>(n);
  t.mean_burst = run_count > 0.0 ? t.lost / run_count : 1.0;
  return t;
}

// ---- iid families: bernoulli and delay --------------------------------------------------------

void fit_iid(const TraceSummary& t, FitResult& r) {
  r.model.transition = Eigen::MatrixXd::Ones(1, 1);
  r.model.emission = Eigen::MatrixXd::Zero(1, t.M);
  r.model.emission(0, 0) = t.lost / t.N;
  for (int d = 0; d <= t.D; ++d)
    r.model.emission(0, d + 1) = t.counts[static_cast<std::size_t>(d + 1)] / t.N;
  r.loglik = t.loss_ll + t.delay_ll;
  r.params.push_back(binomial("loss", t.lost / t.N, t.N));
}

int bernoulli_parameters(const TraceSummary& t, int) {
  if (t.delay_outcomes > 1) {
    throw std::domain_error(
        "the delivered packets have different delays; a bernoulli link has one fixed delay");
  }
  return 1;
}

void fit_bernoulli(const TraceSummary& t, const FitOptions&, FitResult& r) {
  fit_iid(t, r);
  int delay = 0;
  for (int d = 0; d <= t.D; ++d) {
    if (t.counts[static_cast<std::size_t>(d + 1)] > 0.0) delay = d;
  }
  r.link_toml =
      fmt::format("kind = \"bernoulli\"\nloss = {}\ndelay = {}\n", num(t.lost / t.N), delay);
}

void fit_delay(const TraceSummary& t, const FitOptions&, FitResult& r) {
  fit_iid(t, r);
  std::vector<double> pmf;
  for (int d = 0; d <= t.D; ++d) {
    pmf.push_back(t.counts[static_cast<std::size_t>(d + 1)] / t.N);
    r.params.push_back(binomial(fmt::format("pmf[{}]", d), pmf.back(), t.N));
  }
  r.link_toml = fmt::format("kind = \"delay\"\npmf = {}\n", list(pmf));
}

// ---- gilbert_elliott ------------------------------------------------------------------------

// The chain's parameters, the derived mean_loss and mean_burst, and the delays' law.
void gilbert_elliott_parameters(const TraceSummary& t, const FateHmm& b,
                                const std::vector<int>& binary, const FitOptions& o, FitResult& r) {
  Coordinates c;
  Eigen::MatrixXd cov;
  if (o.intervals && t.lost > 0.0 && t.delivered > 0.0) {
    c = free_coordinates(b);
    cov = covariance(b, c, binary);
  }
  const auto ge = [&](const char* name, auto g) { r.params.push_back(wald(name, b, c, cov, g)); };
  ge("p_good_to_bad", [](const FateHmm& h) { return h.transition(0, 1); });
  ge("p_bad_to_good", [](const FateHmm& h) { return h.transition(1, 0); });
  ge("loss_good", [](const FateHmm& h) { return h.emission(0, 0); });
  ge("loss_bad", [](const FateHmm& h) { return h.emission(1, 0); });
  // Mean loss P(L) = pi' e and mean burst P(L) / (P(L) - P(L, L)), P(L, L) = pi' diag(e) T e
  // (e: the loss probability per state), smooth in the free coordinates: delta method.
  const auto loss_pair = [](const FateHmm& h) {
    const Eigen::VectorXd pi = h.stationary();
    const Eigen::VectorXd e = h.emission.col(0);
    return std::make_pair(pi.dot(e), pi.cwiseProduct(e).dot(h.transition * e));
  };
  r.derived.push_back(
      wald("mean_loss", b, c, cov, [&](const FateHmm& h) { return loss_pair(h).first; }));
  r.derived.push_back(wald(
      "mean_burst", b, c, cov,
      [&](const FateHmm& h) {
        const auto [pl, pll] = loss_pair(h);
        return pl > 0.0 && pl > pll ? pl / (pl - pll) : std::nan("");
      },
      1.0, INFINITY));
  if (t.D > 0) {
    for (int d = 0; d <= t.D; ++d)
      r.params.push_back(
          binomial(fmt::format("delay_pmf[{}]", d), t.q[static_cast<std::size_t>(d)], t.delivered));
  }
}

std::string gilbert_elliott_toml(const TraceSummary& t, const FateHmm& b) {
  if (t.D == 0) {
    return fmt::format(
        "kind = \"gilbert_elliott\"\nstep = \"packet\"\np_good_to_bad = {}\np_bad_to_good = "
        "{}\nloss_good = {}\n"
        "loss_bad = {}\n",
        num(b.transition(0, 1)), num(b.transition(1, 0)), num(b.emission(0, 0)),
        num(b.emission(1, 0)));
  }
  const std::vector<double> qq = law(t.q);
  return fmt::format(
      "kind = \"markov\"  # Gilbert–Elliott with state-independent delays\nstep = "
      "\"packet\"\ntransition = [{}, {}]\n"
      "loss = [{}, {}]\ndelay_pmf = [{}, {}]\n",
      list(law({b.transition(0, 0), b.transition(0, 1)})),
      list(law({b.transition(1, 0), b.transition(1, 1)})), num(b.emission(0, 0)),
      num(b.emission(1, 0)), list(qq), list(qq));
}

void fit_gilbert_elliott(const TraceSummary& t, const FitOptions& o, FitResult& r) {
  // The loss indicator carries the chain; the delays are independent of it.
  std::vector<int> binary(t.sym.size());
  for (std::size_t i = 0; i < t.sym.size(); ++i) binary[i] = t.sym[i] == 0 ? 0 : 1;
  EmOutcome em;
  if (t.lost == 0.0 || t.delivered == 0.0) {  // degenerate: one state explains the trace
    em.hmm.transition.resize(2, 2);
    em.hmm.transition << 0.5, 0.5, 0.5, 0.5;
    em.hmm.emission.resize(2, 2);
    const double l = t.lost / t.N;
    em.hmm.emission << l, 1.0 - l, l, 1.0 - l;
    em.loglik = t.loss_ll;
    em.converged = true;
    r.starts = 0;
  } else {
    em = fit_hidden(2, binary, o, r.starts, t.mean_burst);
  }
  r.iterations = em.iterations;
  r.converged = em.converged;
  r.loglik = em.loglik + t.delay_ll;
  const FateHmm& b = em.hmm;
  r.model.transition = b.transition;
  r.model.emission = Eigen::MatrixXd::Zero(2, t.M);
  for (int s = 0; s < 2; ++s) {
    r.model.emission(s, 0) = b.emission(s, 0);
    for (int d = 0; d <= t.D; ++d)
      r.model.emission(s, d + 1) = (1.0 - b.emission(s, 0)) * t.q[static_cast<std::size_t>(d)];
  }
  gilbert_elliott_parameters(t, b, binary, o, r);
  r.link_toml = gilbert_elliott_toml(t, b);
}

// ---- markov<K> ------------------------------------------------------------------------------

void markov_parameters(const TraceSummary& t, const FitOptions& o, FitResult& r) {
  const auto K = static_cast<int>(r.model.transition.rows());
  Coordinates c;
  Eigen::MatrixXd cov;
  if (o.intervals) {
    c = free_coordinates(r.model);
    if (c.entries.size() <= 30)
      cov = covariance(r.model, c, t.sym);
    else
      c.entries.clear(), cov.resize(0, 0);
  }
  const bool have_ci = cov.size() > 0 || (o.intervals && c.entries.empty());
  auto add = [&](const std::string& name, auto g) {
    FitParameter p = wald(name, r.model, c, have_ci ? cov : Eigen::MatrixXd(), g);
    if (!have_ci) p.ci_low = p.ci_high = std::nan("");
    r.params.push_back(p);
  };
  for (int i = 0; i < K; ++i) {
    for (int j = 0; j < K; ++j)
      add(fmt::format("transition[{}][{}]", i, j),
          [i, j](const FateHmm& h) { return h.transition(i, j); });
  }
  for (int i = 0; i < K; ++i)
    add(fmt::format("loss[{}]", i), [i](const FateHmm& h) { return h.emission(i, 0); });
  for (int i = 0; i < K; ++i) {
    for (int d = 0; d <= t.D; ++d) {
      add(fmt::format("delay_pmf[{}][{}]", i, d), [i, d](const FateHmm& h) {
        const double del = 1.0 - h.emission(i, 0);
        return del > 0.0 ? h.emission(i, d + 1) / del : (d == 0 ? 1.0 : 0.0);
      });
    }
  }
}

std::string markov_toml(const TraceSummary& t, const FateHmm& m) {
  const auto K = static_cast<int>(m.transition.rows());
  std::string rows, loss, pmfs;
  for (int i = 0; i < K; ++i) {
    std::vector<double> row;
    for (int j = 0; j < K; ++j) row.push_back(m.transition(i, j));
    std::vector<double> pmf;
    for (int d = 0; d <= t.D; ++d) pmf.push_back(m.emission(i, d + 1));
    if (std::accumulate(pmf.begin(), pmf.end(), 0.0) <= 0.0) pmf.assign(1, 1.0);
    rows += (i ? ", " : "") + list(law(row));
    loss += (i ? ", " : "") + num(m.emission(i, 0));
    pmfs += (i ? ", " : "") + list(law(pmf));
  }
  return fmt::format(
      "kind = \"markov\"\nstep = \"packet\"\ntransition = [{}]\nloss = [{}]\ndelay_pmf = [{}]\n",
      rows, loss, pmfs);
}

void fit_markov(const TraceSummary& t, const FitOptions& o, FitResult& r) {
  const int K = r.states;
  EmOutcome em = fit_hidden(K, t.sym, o, r.starts, t.mean_burst);
  r.iterations = em.iterations;
  r.converged = em.converged;
  r.loglik = em.loglik;
  r.model = em.hmm;
  if (r.model.emission.cols() < t.M) {
    Eigen::MatrixXd e = Eigen::MatrixXd::Zero(K, t.M);
    e.leftCols(r.model.emission.cols()) = r.model.emission;
    r.model.emission = e;
  }
  markov_parameters(t, o, r);
  r.link_toml = markov_toml(t, r.model);
}

// ---- the table ------------------------------------------------------------------------------

struct Family {
  FitFamily info;
  int (*parameters)(const TraceSummary&, int states);  // may refuse the trace (domain_error)
  void (*fit)(const TraceSummary&, const FitOptions&, FitResult&);
};

const std::vector<Family>& families() {
  static const std::vector<Family> all = [] {
    std::vector<Family> f{
        {{"bernoulli",
          "independent losses, one fixed delay (every delivered packet has the same delay); 1 "
          "parameter",
          1, "bernoulli"},
         bernoulli_parameters,
         fit_bernoulli},
        {{"delay",
          "independent packets, delay d with probability pmf[d], lost otherwise; one parameter "
          "per observed outcome but one",
          1, "delay"},
         [](const TraceSummary& t, int) { return t.M - 1; },
         fit_delay},
        {{"gilbert_elliott",
          "hidden two-state chain stepped per packet, a loss probability per state, delays "
          "independent of the state (Baum-Welch from several starts)",
          2, "gilbert_elliott (markov when delays vary)"},
         [](const TraceSummary& t, int) { return 4 + t.D; },
         fit_gilbert_elliott},
    };
    for (int K = 2; K <= 8; ++K) {
      f.push_back(
          {{fmt::format("markov{}", K),
            fmt::format("hidden {}-state chain, per-state loss and delay pmf (Baum-Welch)", K), K,
            "markov"},
           [](const TraceSummary& t, int k) { return k * (k - 1) + k * (t.M - 1); },
           fit_markov});
    }
    return f;
  }();
  return all;
}

const Family* find_family(const std::string& name) {
  for (const auto& f : families()) {
    if (f.info.name == name) return &f;
  }
  return nullptr;
}

}  // namespace

const std::vector<FitFamily>& fit_families() {
  static const std::vector<FitFamily> all = [] {
    std::vector<FitFamily> v;
    for (const auto& f : families()) v.push_back(f.info);
    return v;
  }();
  return all;
}

int family_states(const std::string& family) {
  const Family* f = find_family(family);
  return f != nullptr ? f->info.states : 0;
}

FitResult fit_family(const std::string& family, const std::vector<int>& sym, const FitOptions& o) {
  const Family* f = find_family(family);
  if (f == nullptr) {
    throw std::invalid_argument(fmt::format(
        "unknown family '{}' (expected bernoulli, delay, gilbert_elliott or markov2 .. markov8)",
        family));
  }
  const TraceSummary t = summarise(sym);
  FitResult r;
  r.family = family;
  r.states = f->info.states;
  r.parameters = f->parameters(t, r.states);
  if (t.N < r.parameters) {
    throw std::invalid_argument(
        fmt::format("{} packet(s), fewer than the {} parameters of the {} family", sym.size(),
                    r.parameters, family));
  }
  f->fit(t, o, r);
  r.aic = 2.0 * r.parameters - 2.0 * r.loglik;
  r.bic = r.parameters * std::log(t.N) - 2.0 * r.loglik;
  r.link_toml = fmt::format("[[link]]\nname = \"{}\"\n{}", o.link_name, r.link_toml);
  goodness_of_fit(r, sym, o.acf_lags);
  return r;
}

}  // namespace ncosim::models
