// estimators/sod_jump.cc — the send-on-delta jump observer and its reader. Periodic sensors are
// allowed (jump gain, deterministic design): in the patterns where they did not deliver, their
// gain columns are 0, so a stale held value is never used.
#include "estimators/sod_jump.h"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>

#include "estimators/design/sod_bounds.h"
#include "estimators/kinds.h"
#include "estimators/sod_hold.h"

namespace ncosim::est {

namespace {

using Eigen::MatrixXd;
using Eigen::VectorXd;

class SodJump final : public Estimator {
 public:
  SodJump(const MatrixXd& A, const MatrixXd& C, const std::vector<MatrixXd>& gains,
          const Model& model, const VectorXd& xhat0)
      : A_(A), C_(C), gains_(gains), hold_(model), x_(xhat0), innov_(C.rows()), pred_(A.rows()) {}

  int on_packet(const Packet& p, std::int64_t k) override { return hold_.accept(p, k); }

  void on_period(std::int64_t k, const PeriodInput& in) override {
    if (k > 0) {
      pred_.noalias() = A_ * x_;  // no temporary: nothing allocated per period
      x_ = pred_ + in.drive;
    }
    const std::uint64_t j = hold_.pattern();
    hold_.clear_pattern();
    innov_.noalias() = hold_.m() - C_ * x_;
    x_.noalias() += gains_[j] * innov_;
  }
  StateView state() const override { return StateView(x_.data(), x_.size()); }

 private:
  const MatrixXd& A_;
  const MatrixXd& C_;
  const std::vector<MatrixXd>& gains_;
  SodHold hold_;
  VectorXd x_, innov_, pred_;
};

struct CodesignKeys {
  double mu = 0.0;
  double epsilon = 0.0;
  bool relative = false;
  VectorXd delta0;
  double sigma2_factor = 1.0;
  sod::Assumption assumption = sod::Assumption::kUniform;
  VectorXd r;
};

class SodJumpDesignImpl final : public SodJumpDesign {
 public:
  const SodJumpDesign* sod_codesign() const override { return this; }
  SodJumpDesignImpl(const Model& model, sod::SodSystem sys, sod::SodDesignSpec spec,
                    CodesignKeys cd, VectorXd xhat0, nlohmann::json extra)
      : model_(model),
        sys_(std::move(sys)),
        spec_(std::move(spec)),
        cd_(std::move(cd)),
        xhat0_(std::move(xhat0)) {
    const auto t0 = std::chrono::steady_clock::now();
    const sod::SodDesignResult r = sod::design_sod(sys_, spec_);
    report_.design_seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    report_.method =
        spec_.approach == sod::Approach::kDeterministic ? "lmi_deterministic" : "lmi_stochastic";
    report_.extra = std::move(extra);
    report_.extra["lmis"] = r.lmis;
    report_.extra["sdp_variables"] = r.size.variables;
    report_.extra["sdp_dimension"] = r.size.total_dimension;
    report_.extra["solver_seconds"] = r.seconds;
    if (!r.ok) {
      report_.status = "lmi_" + r.status;
      if (!r.message.empty()) report_.extra["lmi_message"] = r.message;
      gains_.assign(std::size_t{1} << sys_.ns(), MatrixXd::Zero(sys_.A.rows(), sys_.ny()));
    } else {
      gains_ = r.gains;
      report_.extra["guaranteed_bound"] =
          r.bound;  // >= ||z~||^2_RMS under the design's assumptions
      report_.extra["gamma_w"] = r.gamma_w;
      report_.extra["gamma_v"] =
          std::vector<double>(r.gamma_v.data(), r.gamma_v.data() + r.gamma_v.size());
      report_.extra["gamma_delta"] =
          std::vector<double>(r.gamma_delta.data(), r.gamma_delta.data() + r.gamma_delta.size());
      // Spectral radius of the constant-gain / pattern-all error dynamics (I - L C) A.
      const MatrixXd Aall =
          (MatrixXd::Identity(sys_.A.rows(), sys_.A.rows()) - gains_.back() * sys_.C) * sys_.A;
      report_.stable = Aall.eigenvalues().cwiseAbs().maxCoeff() < 1.0;
    }
    report_.stored_gains = spec_.jump ? static_cast<long>(gains_.size()) : 1L;
  }
  std::unique_ptr<Estimator> instantiate() const override {
    return std::make_unique<SodJump>(sys_.A, sys_.C, gains_, model_, xhat0_);
  }
  const DesignReport& report() const override { return report_; }
  std::optional<double> flops_per_period() const override {
    // A x (2n^2 - n) + drive (n) + innovation (2 n ny) + gain (2 n ny).
    const double n = static_cast<double>(sys_.A.rows()), ny = static_cast<double>(sys_.ny());
    return 2 * n * n + 4 * n * ny;
  }
  const sod::SodSystem& system() const override { return sys_; }
  const sod::SodDesignSpec& spec() const override { return spec_; }
  double mu() const override { return cd_.mu; }
  std::optional<sod::CodesignSpec> codesign_spec(double mu, double z0) const override {
    if (sys_.ns() != sys_.ny()) return std::nullopt;  // one output per sensor
    sod::CodesignSpec c;
    c.approach = spec_.approach;
    c.jump = spec_.jump;
    c.vertices = spec_.vertices;
    c.assumption = cd_.assumption;
    c.r = cd_.r;
    c.g = cd_.r;
    c.sigma2_factor = cd_.sigma2_factor;
    c.target = mu * z0;
    const bool det = spec_.approach == sod::Approach::kDeterministic;
    c.relative_step = cd_.epsilon > 0.0 ? cd_.relative : det;
    c.epsilon = cd_.epsilon > 0.0 ? cd_.epsilon : (det ? 0.02 : 0.005);
    c.delta0 = cd_.delta0.size() ? cd_.delta0 : VectorXd(0.01 * cd_.r);
    return c;
  }

 private:
  const Model& model_;
  sod::SodSystem sys_;
  sod::SodDesignSpec spec_;
  CodesignKeys cd_;
  VectorXd xhat0_;
  std::vector<MatrixXd> gains_;
  DesignReport report_;
};

const config::Keys& codesign_keys() {
  using config::Key;
  static const config::Keys keys{
      Key::number("mu").min(1.0).says("mu >= 1").help(
          "the bound on the estimation cost relative to periodic sending (required)"),
      Key::number("epsilon")
          .min(0.0)
          .below(1.0)
          .says("a step in (0, 1) (0: the default)")
          .or_default(0.0)
          .help("cost step (0: 0.02 relative for deterministic, 0.005 absolute for stochastic)"),
      Key::choice("step", {"relative", "absolute"})
          .optional("\"relative\" (deterministic), \"absolute\" (stochastic)")
          .help("relative: J_k = J_{k-1} (1 - epsilon); absolute: J_k = J_{k-1} - epsilon"),
      Key::vector("delta0").optional("0.01 r").help("the starting thresholds, one per output"),
  };
  return keys;
}

const config::Keys& sod_jump_keys() {
  using config::Key;
  static const config::Keys keys =
      config::Keys{
          Key::choice("design", {"deterministic", "stochastic"})
              .or_default("deterministic")
              .help("LMI (11) for every pair of patterns, or LMI (20) at the vertices of the "
                    "probability box"),
          Key::choice("gain", {"jump", "constant"})
              .or_default("jump")
              .help("2^ns gains, or one (Q_j = Q, X_j = X)"),
          Key::number("w_rms")
              .min(0.0)
              .says("||w||_RMS >= 0")
              .help("||w||_RMS of the whole disturbance vector (required)"),
          Key::vector("v_rms")
              .min(0.0)
              .optional("sqrt of the sensors' R diagonals")
              .help("||v_i||_RMS: 1 or total outputs values >= 0"),
          Key::matrix("Cz")
              .or_words({"output"})
              .optional("identity")
              .help("the signal of interest z = Cz x, n columns (\"output\": the stacked "
                    "sensors' C)"),
          Key::vector("delta")
              .min(0.0)
              .optional("the sensors' thresholds")
              .help("thresholds designed for: 1 or total outputs values >= 0"),
          Key::choice("virtual_noise", {"delta2", "delta2_over_3"})
              .or_default("delta2")
              .help("deterministic only: sigma2_delta = delta^2 (the theorem's bound) or "
                    "delta^2 / 3 (delta uniform)"),
          Key::choice("assumption", {"uniform", "gaussian"})
              .or_default("uniform")
              .help("stochastic only: the law of the sensor noise (eqs. 29-30 or 33-34)"),
          Key::vector("r").min(0.0).optional("none").help(
              "stochastic: the uniform range r_i > 0 (or w_inf and v_inf by eq. 28); "
              "deterministic: the co-design cost weights g_i of eq. 35 (default 1)"),
          Key::vector("w_inf").min(0.0).optional("none").help("||w_j||_inf, nw values, for eq. 28"),
          Key::vector("v_inf").min(0.0).optional("none").help(
              "||v_i||_inf, total outputs, for eq. 28"),
          Key::vector("sigma").min(0.0).optional("none").help(
              "sigma_i > 0 of eq. 31 (required with assumption = \"gaussian\")"),
          Key::choice("vertices", {"all", "lower"})
              .or_default("all")
              .help("stochastic only: LMI (20) at every vertex of the box (robust), or only at "
                    "beta = beta'"),
          Key::table("codesign")
              .optional("none")
              .fields(codesign_keys())
              .help("parameters of ncosim codesign: mu (>= 1, required), epsilon, step, delta0"),
      } +
      initial_keys();
  return keys;
}

VectorXd per_output(const config::KeyReader& r, std::string_view key, Eigen::Index ny) {
  VectorXd v = r.vector(key);
  if (v.size() == 1 && ny > 1) v = VectorXd::Constant(ny, v(0));
  if (v.size() != ny || !v.allFinite() || v.minCoeff() < 0.0) {
    r.fail(key, fmt::format("expected 1 or {} non-negative values (one per output), got {}", ny,
                            v.size()));
  }
  return v;
}

// The plant and its outputs (A, Bw, C, the sensors' rows), Cz, w_rms and v_rms; `all_sod`: every
// sensor sends on delta.
sod::SodSystem read_sod_system(const config::KeyReader& r, const Model& model, bool& all_sod) {
  sod::SodSystem sys;
  MatrixXd R;
  stacked_outputs(model, sys.C, R);
  sys.A = model.plant.A;
  sys.Bw = model.plant.Bw;
  sys.sensor_rows.push_back(0);
  all_sod = true;
  for (const auto& s : model.sensors) {
    sys.sensor_rows.push_back(sys.sensor_rows.back() + s.spec.ny());
    const bool sod = s.spec.deadband() != nullptr;
    sys.send_on_delta.push_back(sod);
    all_sod = all_sod && sod;
  }
  const Eigen::Index ny = sys.ny(), n = sys.A.rows();
  if (model.sensors.size() > 6) {
    r.fail("kind", fmt::format("expected at most 6 sensors (2^ns gains and (2^ns)^2 LMIs), got {}",
                               model.sensors.size()));
  }
  const config::Table& t = r.table();
  if (r.has("Cz") && t.is_string("Cz")) {
    t.choice_or("Cz", "output", {"output"});
    sys.Cz = sys.C;  // the signal of interest is the measured output (the paper's example 5.2)
  } else {
    sys.Cz = r.has("Cz") ? r.matrix("Cz") : MatrixXd::Identity(n, n);
  }
  if (sys.Cz.cols() != n)
    r.fail("Cz", fmt::format("expected {} columns (the state size), got {}", n, sys.Cz.cols()));
  sys.w_rms = r.number("w_rms");
  sys.v_rms = r.has("v_rms") ? per_output(r, "v_rms", ny) : VectorXd(R.diagonal().cwiseSqrt());
  return sys;
}

// The stochastic design's keys (vertices, assumption, r | w_inf + v_inf | sigma): beta' and
// sigma2_delta into `spec`, the ranges into `cd`.
void read_stochastic(const config::KeyReader& r, const Model& model, const sod::SodSystem& sys,
                     const VectorXd& delta, sod::SodDesignSpec& spec, CodesignKeys& cd,
                     nlohmann::json& extra) {
  const Eigen::Index ny = sys.ny();
  if (static_cast<Eigen::Index>(model.sensors.size()) != ny) {
    r.fail("design",
           "expected one output per sensor for the stochastic design (beta is per output)");
  }
  const std::string vert = r.string("vertices");
  spec.vertices = vert == "all" ? sod::Vertices::kAll : sod::Vertices::kLower;
  const std::string as = r.string("assumption");
  cd.assumption = as == "uniform" ? sod::Assumption::kUniform : sod::Assumption::kGaussian;
  if (cd.assumption == sod::Assumption::kUniform) {
    if (r.has("r")) {
      cd.r = per_output(r, "r", ny);
    } else if (r.has("w_inf")) {  // (28)
      const VectorXd w_inf = per_output(r, "w_inf", sys.Bw.cols());
      const VectorXd v_inf = per_output(r, "v_inf", ny);
      cd.r = sod::uniform_range(sys.C, sys.Bw, w_inf, v_inf);
    } else {
      r.fail("r",
             "expected the uniform range r (one per output) or w_inf and v_inf to compute it by "
             "(28)");
    }
  } else {
    cd.r = per_output(r, "sigma", ny);
  }
  if (cd.r.minCoeff() <= 0.0)
    r.fail(cd.assumption == sod::Assumption::kUniform ? "r" : "sigma",
           fmt::format("expected values > 0, got {}",
                       fmt::join(cd.r.data(), cd.r.data() + cd.r.size(), ", ")));
  sod::CodesignSpec tmp;
  tmp.approach = spec.approach;
  tmp.assumption = cd.assumption;
  tmp.r = cd.r;
  sod::codesign_bounds(tmp, delta, spec.sigma2_delta, spec.beta_lower);
  extra["vertices"] =
      vert == "all" ? "all (robust over the probability box)" : "lower (beta = beta' only)";
  extra["assumption"] = as;
  extra[cd.assumption == sod::Assumption::kUniform ? "r" : "sigma"] =
      std::vector<double>(cd.r.data(), cd.r.data() + ny);
  extra["beta_lower"] = std::vector<double>(spec.beta_lower.data(), spec.beta_lower.data() + ny);
}

// [codesign]: the parameters of `ncosim codesign`.
void read_codesign(const config::KeyReader& r, const sod::SodDesignSpec& spec, Eigen::Index ny,
                   CodesignKeys& cd) {
  const auto table = r.opt_table("codesign");
  if (!table) return;
  const config::KeyReader c(*table, codesign_keys());
  cd.mu = c.number("mu");
  cd.epsilon = c.number("epsilon");
  const char* step = spec.approach == sod::Approach::kDeterministic ? "relative" : "absolute";
  cd.relative = c.opt_string("step").value_or(step) == "relative";
  if (c.has("delta0")) cd.delta0 = per_output(c, "delta0", ny);
  table->finish();
}

std::unique_ptr<EstimatorDesign> read_sod_jump(const config::Table& t, const Model& model) {
  const config::KeyReader r(t, sod_jump_keys());
  bool all_sod = true;
  sod::SodSystem sys = read_sod_system(r, model, all_sod);
  const Eigen::Index ny = sys.ny();
  sod::SodDesignSpec spec;
  const std::string approach = r.string("design");
  spec.approach =
      approach == "deterministic" ? sod::Approach::kDeterministic : sod::Approach::kStochastic;
  spec.jump = r.string("gain") == "jump";
  if (!spec.jump && !all_sod) {
    r.fail("gain",
           "expected gain = \"jump\" with periodic sensors (a constant gain would use their stale "
           "held values), got \"constant\"");
  }
  VectorXd delta = r.has("delta") ? per_output(r, "delta", ny) : stacked_delta(model);

  CodesignKeys cd;
  nlohmann::json extra;
  extra["design"] = approach;
  extra["gain"] = spec.jump ? "jump" : "constant";
  extra["delta"] = std::vector<double>(delta.data(), delta.data() + delta.size());
  if (spec.approach == sod::Approach::kDeterministic) {
    const std::string vn = r.string("virtual_noise");
    cd.sigma2_factor = vn == "delta2" ? 1.0 : 1.0 / 3.0;
    spec.sigma2_delta = cd.sigma2_factor * delta.cwiseProduct(delta);
    extra["virtual_noise"] = vn;
    // The deterministic co-design weights g_i = r_i (35) when given.
    cd.r = r.has("r") ? per_output(r, "r", ny) : VectorXd::Ones(ny);
  } else {
    if (!all_sod) r.fail("design", "expected send_on_delta sensors only for the stochastic design");
    read_stochastic(r, model, sys, delta, spec, cd, extra);
  }
  extra["sigma2_delta"] =
      std::vector<double>(spec.sigma2_delta.data(), spec.sigma2_delta.data() + ny);
  read_codesign(r, spec, ny, cd);
  InitialEstimate init = read_initial(t, model);
  return std::make_unique<SodJumpDesignImpl>(model, std::move(sys), std::move(spec), std::move(cd),
                                             std::move(init.xhat0), std::move(extra));
}

// One LMI problem (estimators/design/sod_design.cc), sized before it is built and costed by the
// LMI layer's formula (lmi/lmi.cc, Problem::Impl::estimate: 50 interior-point iterations of a
// Schur complement build and factorisation): with p = 2^sensors delivery patterns, variables Q_j,
// X_j per pattern (one with gain = "constant"), P_j per pattern (deterministic) or one
// (stochastic); the deterministic design has p^2 LMIs of 2n + nw + 2ny rows, the stochastic one
// an LMI of p n + n + nw + 2 ny rows per vertex. The LMI layer checks its own estimate again when
// the problem is built.
DesignCost sod_jump_cost(const config::Table& /*t*/, const toml::table& raw, const Model& model,
                         const std::string& /*driver*/) {
  const double n = static_cast<double>(model.plant.n());
  const double ny = static_cast<double>(model.total_outputs());
  const double nw = static_cast<double>(model.plant.nw());
  const double ns = static_cast<double>(model.sensors.size());
  auto peek = [&raw](const char* key) { return peek_string(raw, sod_jump_keys().at(key)); };
  const bool det = peek("design") != "stochastic";
  const bool jump = peek("gain") != "constant";
  const double p = std::ldexp(1.0, static_cast<int>(std::min(ns, 20.0)));
  const double k =
      (jump ? p : 1.0) * (n * n + n * ny) + (det ? p : 1.0) * n * (n + 1.0) / 2.0 + 1.0 + 2.0 * ny;
  const double lmis = det ? p * p : (peek("vertices") == "lower" ? 1.0 : p);
  const double m = det ? 2.0 * n + nw + 2.0 * ny : p * n + n + nw + 2.0 * ny;
  const double flops = 50.0 * (k * k * m + k * k * k / 3.0 + 10.0 * lmis * m * m * m);
  const double bytes = 16.0 * k * k + 11.0 * lmis * 8.0 * m * m + 48.0 * lmis * m * m * 4.0;
  return {bytes, flops, ""};
}

}  // namespace

void register_sod_jump(EstimatorRegistry& registry) {
  registry.add("sod_jump",
               "send-on-delta jump observer, H-infinity LMI design (send-on-delta co-design "
               "paper): design = "
               "\"deterministic\" (LMI 11) | \"stochastic\" (LMI 20 at the vertices), gain = "
               "\"jump\" | \"constant\", "
               "w_rms, v_rms, virtual_noise, r | w_inf + v_inf | sigma, assumption, vertices, "
               "delta, Cz, [codesign]",
               sod_jump_keys(), read_sod_jump, sod_jump_cost);
}

}  // namespace ncosim::est
