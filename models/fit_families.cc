// models/fit_families.cc — the fit families of `ncosim fit` as declared entries (models/fit.h):
// each names itself, its hidden states, the [[link]] kind it writes, its parameter count and its
// fit; fit_family() looks the name up once (no family is compared by name elsewhere).
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <optional>
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

// Laws of the delivered packets' delays longer than this are summarised in `ncosim fit`'s
// printout (mean delay), every bin staying in fit.json and fit.csv.
constexpr int kSummaryBins = 6;

// The delivered packets' count per delay (d = 0 .. D).
std::vector<double> delivered_counts(const TraceSummary& t) {
  return {t.counts.begin() + 1, t.counts.end()};
}

void fit_iid(const TraceSummary& t, FitResult& r) {
  r.model.transition = Eigen::MatrixXd::Ones(1, 1);
  r.model.emission = Eigen::MatrixXd::Zero(1, t.M);
  r.model.emission(0, 0) = t.lost / t.N;
  for (int d = 0; d <= t.D; ++d)
    r.model.emission(0, d + 1) = t.counts[static_cast<std::size_t>(d + 1)] / t.N;
  r.loglik = t.loss_ll + t.delay_ll;
  r.params.push_back(binomial("loss", t.lost / t.N, t.N));
  if (t.D > 0) r.derived.push_back(mean_delay("mean_delay", delivered_counts(t)));
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
    r.params.back().summary = t.D < kSummaryBins;
  }
  r.link_toml = fmt::format("kind = \"delay\"\npmf = {}\n", list(pmf));
}

// ---- hidden families: their parameters' intervals -------------------------------------------

// Where a parameter sits in the model: entry (row, col) of the transition or emission matrix;
// `scale` maps the entry to the parameter (a conditional delay law: 1 / P(delivered)).
struct Entry {
  bool emission = false;
  Eigen::Index row = 0, col = 0;
  double scale = 1.0;
};

// What the intervals of a hidden family's parameters are computed from.
struct Information {
  Information(const FateHmm& model, const std::vector<int>& s, bool on) : h(model), sym(s) {
    if (!on) return;
    intervals = true;
    c = free_coordinates(h);
    cov = hidden_covariance(h, c, sym, why);
  }
  const FateHmm& h;
  const std::vector<int>& sym;
  bool intervals = false;
  Coordinates c;
  Eigen::MatrixXd cov;
  std::string why;  // set when `cov` could not be computed

  // g(h) with its interval: Wald on `cov`; a likelihood-ratio bound at `entry` when that comes
  // out degenerate (the fit put the entry at 0 or 1); none, with a note, when `cov` is missing.
  template <class G>
  FitParameter parameter(const std::string& name, G g, std::optional<Entry> entry = std::nullopt,
                         double lo = 0.0, double hi = 1.0) const {
    FitParameter p;
    if (!intervals) {
      p.name = name;
      p.estimate = g(h);
      p.ci_low = p.ci_high = std::nan("");
      return p;
    }
    p = wald(name, h, c, cov, g, lo, hi);
    if (!why.empty()) {
      p.note = why;
      return p;
    }
    const double width = p.ci_high - p.ci_low;
    if (!std::isfinite(width) || width > 1e-12 * std::max(1.0, std::abs(p.estimate))) return p;
    if (entry) {
      likelihood_ratio_interval(p, h, entry->emission, entry->row, entry->col, sym, entry->scale);
    } else {
      p.ci_low = p.ci_high = std::nan("");
      p.interval.clear();
      p.note = "no interval: its parameters are at the edge of their range";
    }
    return p;
  }
};

// The note of a family whose EM stopped at its cap.
std::string cap_note(const FitOptions& o) {
  return fmt::format(
      "not converged: the EM stopped at its cap of {} iterations with the log-likelihood still "
      "rising (not a maximum; never selected)",
      o.max_iterations);
}

// ---- gilbert_elliott ------------------------------------------------------------------------

// The chain's parameters, the derived mean_loss and mean_burst, and the delays' law.
void gilbert_elliott_parameters(const TraceSummary& t, const FateHmm& b,
                                const std::vector<int>& binary, const FitOptions& o, FitResult& r) {
  const bool identified = t.lost > 0.0 && t.delivered > 0.0;
  const Information info(b, binary, o.intervals && identified);
  const auto ge = [&](const char* name, Entry e, auto g) {
    r.params.push_back(info.parameter(name, g, e));
    if (o.intervals && !identified)
      r.params.back().note =
          "no interval: without both losses and deliveries the chain is not "
          "identified";
  };
  ge("p_good_to_bad", {false, 0, 1}, [](const FateHmm& h) { return h.transition(0, 1); });
  ge("p_bad_to_good", {false, 1, 0}, [](const FateHmm& h) { return h.transition(1, 0); });
  ge("loss_good", {true, 0, 0}, [](const FateHmm& h) { return h.emission(0, 0); });
  ge("loss_bad", {true, 1, 0}, [](const FateHmm& h) { return h.emission(1, 0); });
  // Mean loss P(L) = pi' e and mean burst P(L) / (P(L) - P(L, L)), P(L, L) = pi' diag(e) T e
  // (e: the loss probability per state), smooth in the free coordinates: delta method.
  const auto loss_pair = [](const FateHmm& h) {
    const Eigen::VectorXd pi = h.stationary();
    const Eigen::VectorXd e = h.emission.col(0);
    return std::make_pair(pi.dot(e), pi.cwiseProduct(e).dot(h.transition * e));
  };
  if (identified || !o.intervals) {
    r.derived.push_back(
        info.parameter("mean_loss", [&](const FateHmm& h) { return loss_pair(h).first; }));
  } else {
    r.derived.push_back(binomial("mean_loss", t.lost / t.N, t.N));
  }
  r.derived.push_back(info.parameter(
      "mean_burst",
      [&](const FateHmm& h) {
        const auto [pl, pll] = loss_pair(h);
        return pl > 0.0 && pl > pll ? pl / (pl - pll) : std::nan("");
      },
      std::nullopt, 1.0, INFINITY));
  if (t.D > 0) {
    r.derived.push_back(mean_delay("mean_delay", delivered_counts(t)));
    for (int d = 0; d <= t.D; ++d) {
      r.params.push_back(
          binomial(fmt::format("delay_pmf[{}]", d), t.q[static_cast<std::size_t>(d)], t.delivered));
      r.params.back().summary = t.D < kSummaryBins;
    }
  }
  if (!info.why.empty()) r.note += (r.note.empty() ? "" : "; ") + info.why;
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
    r.iteration_cap = o.max_iterations;
  }
  r.iterations = em.iterations;
  r.converged = em.converged;
  if (!r.converged) r.note = cap_note(o);
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

// Transitions (every entry up to 3 states, else the stays in the summary), per-state losses,
// per-state delay laws (summarised by their mean delay when long).
void markov_parameters(const TraceSummary& t, const FitOptions& o, FitResult& r) {
  const auto K = static_cast<int>(r.model.transition.rows());
  const Information info(r.model, t.sym, o.intervals);
  auto add = [&](const std::string& name, std::optional<Entry> e, bool summary, auto g) {
    r.params.push_back(info.parameter(name, g, e));
    r.params.back().summary = summary;
  };
  for (int i = 0; i < K; ++i) {
    for (int j = 0; j < K; ++j)
      add(fmt::format("transition[{}][{}]", i, j), Entry{false, i, j}, K <= 3 || i == j,
          [i, j](const FateHmm& h) { return h.transition(i, j); });
  }
  for (int i = 0; i < K; ++i)
    add(fmt::format("loss[{}]", i), Entry{true, i, 0}, true,
        [i](const FateHmm& h) { return h.emission(i, 0); });
  for (int i = 0; i < K; ++i) {
    const double delivered = 1.0 - r.model.emission(i, 0);
    const double scale = delivered > 0.0 ? 1.0 / delivered : std::nan("");
    for (int d = 0; d <= t.D; ++d) {
      add(fmt::format("delay_pmf[{}][{}]", i, d), Entry{true, i, d + 1, scale},
          t.D < kSummaryBins / 2, [i, d](const FateHmm& h) {
            const double del = 1.0 - h.emission(i, 0);
            return del > 0.0 ? h.emission(i, d + 1) / del : (d == 0 ? 1.0 : 0.0);
          });
    }
    if (t.D == 0) continue;
    r.derived.push_back(info.parameter(
        fmt::format("mean_delay[{}]", i),
        [i, D = t.D](const FateHmm& h) {
          double m = 0.0;
          for (int d = 1; d <= D; ++d) m += d * h.emission(i, d + 1);
          const double del = 1.0 - h.emission(i, 0);
          return del > 0.0 ? m / del : std::nan("");
        },
        std::nullopt, 0.0, INFINITY));
  }
  if (!info.why.empty()) r.note += (r.note.empty() ? "" : "; ") + info.why;
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
  r.iteration_cap = o.max_iterations;
  r.converged = em.converged;
  if (!r.converged) r.note = cap_note(o);
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
