// estimators/jump_observer.cc
// Jump linear observer with precomputed gains L(N, pattern) (Dolz et al. 2014, eqs. 6, 10, 16).
// Between arrivals it runs open loop on the delay-extended state; on arrival it applies the
// gain selected by the periods since the previous update (clamped to Nbar) and the grouping
// S1..S4 of the delivered fictitious sensors. Never throws on a step; a failed design is
// reported at construction (design.json) and on every row (status).
#include "estimators/jump_observer.h"

#include <fmt/format.h>

#include <bit>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <optional>

#include "estimators/delay_window.h"
#include "estimators/design/ccl_design.h"
#include "estimators/design/jump_design.h"
#include "estimators/extended_model.h"
#include "estimators/kinds.h"

namespace ncosim::est {

namespace {

struct JumpParams {
  Grouping grouping;
  int Nbar;
  int dbar;
  std::string design = "iterative";  // "iterative", "ccl" or "both"
  std::string ccl_start = "s4";  // "s4" (anchored at the exact S4 design) or "paper" (as printed)
  bool verbose = false;
  InitialEstimate init;
};

class JumpObserver final : public Estimator {
 public:
  JumpObserver(const ExtendedModel& ext, const JumpDesign& design, const InitialEstimate& init)
      : ext_(ext),
        design_(design),
        window_(ext, /*deduplicate=*/false),
        x_(ext.nb),
        head_(ext.n),
        innov_(Eigen::VectorXd::Zero(ext.nmb)),
        masks_(design.masks) {
    for (int b = 0; b <= ext.dbar; ++b) x_.segment(b * ext.n, ext.n) = init.xhat0;
  }

  int on_packet(const Packet& p, std::int64_t k) override { return window_.accept(p, k); }

  void on_period(std::int64_t k, const PeriodInput& in) override {
    window_.advance(k);
    const Eigen::Index n = ext_.n;
    if (k > 0) {  // eq. (6): xhat[t-] = Abar xhat[t-1] + Bbar_u u[t-1]
      head_.noalias() = ext_.A.topLeftCorner(n, n).lazyProduct(x_.head(n));  // lazy: small sizes
      for (int b = ext_.dbar; b >= 1; --b) x_.segment(b * n, n) = x_.segment((b - 1) * n, n);
      x_.head(n) = head_ + in.drive;
    }
    const std::uint64_t pattern = window_.pattern();
    if (pattern != 0 && design_.stable) {
      const int N = static_cast<int>(std::min<std::int64_t>(k - last_update_, design_.Nbar));
      const Eigen::MatrixXd& L = design_.gains[design_.gain_of[N - 1][pattern]];
      // eq. (10): xhat += L alpha (mbar - Cbar xhat); alpha is the row mask of the pattern.
      innov_ = window_.values();  // (two steps: no temporary allocated in the hot path)
      innov_.noalias() -= ext_.C.lazyProduct(x_);
      innov_.array() *= masks_[pattern].array();
      x_.noalias() += L.lazyProduct(innov_);
      last_update_ = k;
    }
    window_.clear_pattern();
  }

  StateView state() const override { return StateView(x_.data(), ext_.n); }
  const Eigen::VectorXd* extended() const override { return &x_; }
  std::string status() const override { return design_.stable ? "ok" : row_status_; }
  void set_row_status(std::string s) { row_status_ = std::move(s); }

 private:
  const ExtendedModel& ext_;
  const JumpDesign& design_;
  DelayWindow window_;
  Eigen::VectorXd x_;
  Eigen::VectorXd head_;
  Eigen::VectorXd innov_;
  const std::vector<Eigen::VectorXd>& masks_;
  std::int64_t last_update_ = -1;
  std::string row_status_ = "design_failed";
};

class JumpObserverDesign final : public EstimatorDesign, public JumpDesignAccess {
 public:
  const JumpDesignAccess* c_export() const override { return this; }
  JumpObserverDesign(const Model& model, JumpParams params)
      : params_(std::move(params)), ext_(build_extended(model, params_.dbar)) {
    const auto probs = pattern_probabilities(model, ext_);
    std::optional<JumpDesign> iterative, ccl;
    double t_iter = 0.0, t_ccl = 0.0;
    CclInfo info;
    if (params_.design != "ccl") iterative = design_iterative(probs, t_iter);
    if (params_.design != "iterative") ccl = design_ccl(probs, info, t_ccl);
    const bool use_ccl =
        !iterative ||
        (ccl && ccl->stable && (!iterative->stable || ccl->Pt.trace() < iterative->Pt.trace()));
    design_ = use_ccl ? *ccl : *iterative;
    report_.method = use_ccl ? "ccl" : "iterative";
    report_.design_seconds = t_iter + t_ccl;
    report_chosen();
    report_.extra["design"] = params_.design;
    if (ccl) report_.extra["ccl_start"] = params_.ccl_start;
    if (iterative) report_iterative(*iterative, t_iter);
    if (ccl) report_ccl(*ccl, info, t_ccl);
    if (iterative && ccl) report_.extra["chosen"] = report_.method;
    // A failed iterative design keeps its historical row status; a failed LMI design is
    // design_<lmi status> (design_infeasible, design_numerical_trouble, ...).
    row_status_ = use_ccl ? "design_" + design_.status : "design_failed";
    static const char* names[] = {"S1", "S2", "S3", "S4"};
    report_.extra["grouping"] = names[static_cast<int>(params_.grouping)];
    report_.extra["history"] = params_.Nbar;
    report_.extra["max_delay"] = params_.dbar;
    report_.extra["p0"] = design_.p0;
  }

  std::unique_ptr<Estimator> instantiate() const override {
    auto e = std::make_unique<JumpObserver>(ext_, design_, params_.init);
    e->set_row_status(row_status_);
    return e;
  }
  const DesignReport& report() const override { return report_; }
  std::optional<double> flops_per_period() const override {
    // Dolz et al. section 2: nb^2 + nb nu + 2 nb nmb + 2 nb + nmb.
    const double nb = static_cast<double>(ext_.nb), nu = static_cast<double>(ext_.nu);
    const double nmb = static_cast<double>(ext_.nmb);
    return nb * nb + nb * nu + 2 * nb * nmb + 2 * nb + nmb;
  }
  Eigen::Index extended_size() const override { return ext_.nb; }
  bool models_independent_fictitious_sensors() const override { return true; }
  const ExtendedModel& extended_model() const override { return ext_; }
  const JumpDesign& jump_design() const override { return design_; }
  const InitialEstimate& initial_estimate() const override { return params_.init; }

 private:
  static double seconds_since(std::chrono::steady_clock::time_point start) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  }

  // The value-iteration design, reported through evaluate_jump_gains like CCL, so that both
  // predictions are computed alike.
  JumpDesign design_iterative(const std::vector<double>& probs, double& seconds) const {
    const auto start = std::chrono::steady_clock::now();
    JumpDesign it = design_jump_iterative(ext_, probs, params_.Nbar, params_.grouping);
    if (it.stable) {
      JumpDesign ev = evaluate_jump_gains(ext_, probs, params_.Nbar, params_.grouping, it.gains);
      if (ev.stable) {
        ev.iterations = it.iterations;
        it = std::move(ev);
      }
    }
    seconds = seconds_since(start);
    return it;
  }

  JumpDesign design_ccl(const std::vector<double>& probs, CclInfo& info, double& seconds) const {
    const auto start = std::chrono::steady_clock::now();
    CclOptions o;
    o.verbose = params_.verbose;
    if (params_.ccl_start == "paper") {  // section 4's steps (bench: BM_DesignCclLiteral)
      o.start = CclStart::kFeasible;
      o.patience = o.max_ccl_iterations;
      o.s4_bound = false;
    }
    JumpDesign d = design_jump_ccl(ext_, probs, params_.Nbar, params_.grouping, o, &info);
    seconds = seconds_since(start);
    return d;
  }

  // The chosen design's figures.
  void report_chosen() {
    report_.stored_gains = design_.stored_gains;
    report_.stable = design_.stable;
    report_.status = design_.status;
    if (!design_.stable) return;
    report_.predicted_mse_ext = design_.Pt.trace();
    report_.predicted_mse = design_.Pt.topLeftCorner(ext_.n, ext_.n).trace();
    // The paper's printed eq. (28), which is wrong: only to reproduce its Fig. 3
    // (results/README.md).
    report_.extra["predicted_mse_paper_eq28_erroneous"] =
        design_.Pt_paper_eq28_erroneous.topLeftCorner(ext_.n, ext_.n).trace();
    report_.extra["predicted_mse_ext_paper_eq28_erroneous"] =
        design_.Pt_paper_eq28_erroneous.trace();
  }

  void report_iterative(const JumpDesign& iterative, double t_iter) {
    report_.extra["design_seconds_iterative"] = t_iter;
    report_.extra["iterations"] = iterative.iterations;
    if (iterative.stable)
      report_.extra["predicted_mse_ext_iterative"] = iterative.Pt.trace();
    else
      report_.extra["status_iterative"] = iterative.status;
    if (!iterative.iteration_message.empty())
      report_.extra["iteration_message"] = iterative.iteration_message;
  }

  void report_ccl(const JumpDesign& ccl, const CclInfo& info, double t_ccl) {
    report_.extra["design_seconds_ccl"] = t_ccl;
    if (ccl.stable)
      report_.extra["predicted_mse_ext_ccl"] = ccl.Pt.trace();
    else
      report_.extra["status_ccl"] = ccl.status;
    report_.extra["sdp"] = {{"variables", info.size.variables},
                            {"blocks", info.size.blocks},
                            {"block_sizes", info.size.block_sizes},
                            {"solves", info.sdp_solves},
                            {"bisections", info.bisections},
                            {"ccl_iterations", info.ccl_iterations},
                            {"relaxation_trP", info.relaxation_bound},
                            {"s4_bound_trP", info.s4_bound},
                            {"bisection_stop", info.stop.empty() ? "none" : info.stop},
                            {"bisection_low_trP", info.lower_bound},
                            {"bisection_high_trP", info.upper_bound}};
  }
  JumpParams params_;
  ExtendedModel ext_;
  JumpDesign design_;
  DesignReport report_;
  std::string row_status_ = "design_failed";
};

const config::Keys& jump_keys() {
  using config::Key;
  static const config::Keys keys =
      config::Keys{
          Key::choice("grouping", {"S1", "S2", "S3", "S4"})
              .or_default("S4")
              .help("gain sharing: S1 one gain per N; S2 per number of real sensors delivered; S3 "
                    "per "
                    "number of fictitious sensors delivered; S4 per availability pattern (2^nf - 1 "
                    "per N)"),
          Key::integer("history").range(1, 1000).or_default(1).unit("periods").help(
              "N-bar: gains per N = 1 .. N-bar (N-bar covers N >= N-bar); history x 2^nf <= 2^18"),
          max_delay_key().or_default(0).help(
              "d-bar; nf = sensors x (max_delay + 1) <= 20 (<= 16 for S4)"),
          Key::choice("design", {"iterative", "ccl", "both"})
              .or_default("iterative")
              .help("design method: value iteration, the paper's LMI method (cone-complementarity "
                    "linearisation in a bisection on tr(P)), or both (keeps the lower predicted "
                    "tr(Pt))"),
          Key::choice("ccl_start", {"s4", "paper"})
              .or_default("s4")
              .help("how ccl starts: at the exact S4 design (fast), or by the paper's section 4 "
                    "steps (10-100x slower)"),
      } +
      initial_keys();
  return keys;
}

// The sizes read_jump refuses, each with its own message: fictitious sensors (sensors x
// (max_delay + 1)) up to 20, history x 2^(fictitious sensors) terms up to 2^18, and S4 (which
// stores every pattern's gains) up to 16 fictitious sensors.
constexpr int kMaxFictitiousSensors = 20;
constexpr double kMaxTerms = 262144.0;
constexpr int kMaxS4FictitiousSensors = 16;

bool jump_size_supported(double nf, double history, bool s4) {
  return nf <= kMaxFictitiousSensors &&
         history * std::ldexp(1.0, static_cast<int>(nf)) <= kMaxTerms &&
         !(s4 && nf > kMaxS4FictitiousSensors);
}

std::unique_ptr<EstimatorDesign> read_jump(const config::Table& t, const Model& model) {
  const config::KeyReader r(t, jump_keys());
  JumpParams p;
  const std::string g = r.string("grouping");
  p.grouping = static_cast<Grouping>(g[1] - '1');
  p.Nbar = static_cast<int>(r.integer("history"));
  p.dbar = static_cast<int>(r.integer("max_delay"));
  p.design = r.string("design");
  p.ccl_start = r.string("ccl_start");
  // CSDP's iteration log on stderr (it is never written to stdout).
  const char* lmi_log = std::getenv("NCOSIM_LMI_VERBOSE");
  p.verbose = lmi_log != nullptr && std::string(lmi_log) == "1";
  p.init = read_initial(t, model);
  const int nf = static_cast<int>(model.sensors.size()) * (p.dbar + 1);
  if (nf > kMaxFictitiousSensors) {
    t.fail("max_delay", fmt::format("the design enumerates 2^{} availability patterns "
                                    "({} sensors x {} delays); at most 2^20 are supported",
                                    nf, model.sensors.size(), p.dbar + 1));
  }
  // The design sums over every (N, pattern) term at each iteration: bound the work.
  if (static_cast<double>(p.Nbar) * std::ldexp(1.0, nf) > kMaxTerms) {
    t.fail("history",
           fmt::format("the design has history x 2^(fictitious sensors) = {} x 2^{} terms; "
                       "at most 2^18 are supported (reduce history, max_delay or sensors)",
                       p.Nbar, nf));
  }
  if (p.grouping == Grouping::kS4 && nf > kMaxS4FictitiousSensors) {
    t.fail("grouping", fmt::format("S4 stores (2^{} - 1) gains per N; use S1..S3 or fewer "
                                   "delays (at most 16 fictitious sensors for S4)",
                                   nf));
  }
  return std::make_unique<JumpObserverDesign>(model, std::move(p));
}

// Three parts, all on the delay-extended state of nb = n (max_delay + 1) rows, where the design
// works (estimators/design/jump_design.cc; nyf = ny (max_delay + 1) fictitious outputs):
// - the generic estimate on the plant state;
// - history x 2^(fictitious sensors) terms (the stored gains of S4, the patterns of the others),
//   each with a gain nb x nyf (two copies) and an update of the nb x nb covariance over ~50
//   iterations. Memory per term: the gains and a nyf x nyf matrix (measured on Table 2's A3 with
//   S4: 1.9, 3.1 and 4.3 kB per term at nyf = 12, 14, 16, i.e. max_delay 5, 6, 7; 1.1 GB at history
//   4, max_delay 7, where this formula gives 1.6 GB);
// - the operators on vec(P), m x m with m = nb^2, that every design builds: the Stein operator
//   (an m x m inverse, history_terms, twice) and, in evaluate_jump_gains, the operator of (18)
//   with fixed gains (a product by the Stein operator), its spectral radius (a nonsymmetric
//   eigenvalue solve) and an LU solve. The eigenvalue solve dominates: measured in one thread at
//   33-49 m^3 flops at the rate of a 192 x 192 product for m = 144 .. 1296, but 96 at m = 256
//   and 191 at m = 1024 (the Francis steps' row sweeps on a leading dimension of a power of two
//   alias in the cache); 100 m^3 covers both within 3x, 110 m^3 with the rest, and about 8 m x m
//   matrices are alive (measured 3.7 MB at nb = 16, 17-19 MB at nb = 24). This part was missing:
//   n = 8, max_delay = 3 (nb = 32, 2 sensors, S3, history 2) took 27 s of design, 80 % of it in
//   the eigenvalue solve of a 1024 x 1024 operator, against an estimate of 0.02 s.
// The ccl design's LMIs are estimated by the LMI layer when they are built.
DesignCost jump_cost(const config::Table& t, const toml::table& raw, const Model& model,
                     const std::string& driver) {
  const double n = static_cast<double>(model.plant.n());
  const double ny = static_cast<double>(model.total_outputs());
  const double sensors = static_cast<double>(model.sensors.size());
  const std::int64_t dbar = peek_integer(raw, jump_keys().at("max_delay"));
  const std::int64_t history = peek_integer(raw, jump_keys().at("history"));
  DesignCost c = generic_design_cost(model);
  const double nf = sensors * static_cast<double>(dbar + 1);
  // A size the reader refuses: no design will run, and the reader's message (which key, what is
  // supported) is the one to see, not a limit on an estimate of a design that cannot be made.
  if (!jump_size_supported(nf, static_cast<double>(history),
                           peek_string(raw, jump_keys().at("grouping")) == "S4")) {
    return c;
  }
  const double terms =
      static_cast<double>(history) * std::ldexp(1.0, static_cast<int>(std::min(nf, 60.0)));
  const double nb = n * static_cast<double>(dbar + 1);
  const double nyf = ny * static_cast<double>(dbar + 1);
  c.bytes += terms * 8.0 * (nyf * nyf + 2.0 * nb * nyf);
  c.flops += 50.0 * terms * (2.0 * nb * nb * nb + 2.0 * nb * nyf * nyf + nyf * nyf * nyf);
  const double m = nb * nb;
  c.bytes += 8.0 * 8.0 * m * m;
  c.flops += 110.0 * m * m * m;
  c.driver = fmt::format("{} and {} ({} x 2^{} terms, {})", t.key_path("history"),
                         t.key_path("max_delay"), history, nf, driver);
  return c;
}

}  // namespace

void register_jump(EstimatorRegistry& registry) {
  registry.add("jump",
               "jump observer with precomputed gains L(N, pattern), Dolz et al. 2014: grouping "
               "(S1..S4), history (Nbar), max_delay (dbar), design (iterative, ccl or both)",
               jump_keys(), read_jump, jump_cost);
}

}  // namespace ncosim::est
