// estimators/sod_kalman.cc
// The modified Kalman filter of Suh, Nguyen and Ro (2007) for send-on-delta sensors, the
// comparison of the send-on-delta co-design paper (example 5.1): every period it updates with
// the held measurement vector m; an output whose sensor did not send this period gets the
// extra "virtual noise" variance factor * delta_i^2 (factor 1/3: delta uniform on
// [-delta_i, delta_i]) on top of its noise variance R. Outputs never received are skipped, and
// so are the held values of periodic sensors (no threshold) that did not deliver this period:
// with periodic sensors the filter is the Kalman filter with intermittent observations. A
// send-on-delta sensor's silence is read as "within delta": the filter assumes its link
// delivers every sent sample in the period it is sent.
#include <fmt/format.h>

#include "estimators/kalman_update.h"
#include "estimators/kinds.h"
#include "estimators/sod_hold.h"

namespace ncosim::est {

namespace {

struct SodKalmanParams {
  Eigen::MatrixXd A, Q, C, R;       // Q = Bw W Bw' (the filter's W)
  Eigen::VectorXd virtual_var;      // factor * delta^2 per stacked output
  std::vector<bool> send_on_delta;  // per sensor
  InitialEstimate init;
};

class SodKalman final : public Estimator {
 public:
  SodKalman(const SodKalmanParams& p, const Model& model)
      : p_(p),
        hold_(model),
        x_(p.init.xhat0),
        P_(p.init.P0),
        ws_(p.A.rows(), p.C.rows()),
        rows_(static_cast<std::size_t>(p.C.rows())) {}

  int on_packet(const Packet& p, std::int64_t k) override { return hold_.accept(p, k); }

  void on_period(std::int64_t k, const PeriodInput& in) override {
    if (k > 0) {
      kalman::predict_state(p_.A, x_, ws_);
      x_ += in.drive;
      kalman::predict_covariance(p_.A, p_.Q, P_, ws_);
    }
    const std::uint64_t fresh = hold_.pattern();
    hold_.clear_pattern();
    Eigen::Index m = 0;
    for (std::size_t s = 0; s < hold_.sensors(); ++s) {
      if (!use(s, fresh)) continue;
      for (Eigen::Index i = 0; i < hold_.ny(s); ++i)
        rows_[static_cast<std::size_t>(m++)] = hold_.offset(s) + i;
    }
    if (m == 0) return;
    kalman::select(p_.C, p_.R, hold_.m(), rows_.data(), m, ws_);
    // Virtual noise on the outputs of the sensors that did not send this period.
    Eigen::Index row = 0;
    for (std::size_t s = 0; s < hold_.sensors(); ++s) {
      if (!use(s, fresh)) continue;
      const bool sent = (fresh >> s) & 1U;
      for (Eigen::Index i = 0; i < hold_.ny(s); ++i, ++row) {
        if (!sent) ws_.R(row, row) += p_.virtual_var(hold_.offset(s) + i);
      }
    }
    if (!kalman::update(x_, P_, ws_, &innovations_)) {
      failed_ = true;
      return;
    }
    if (!x_.allFinite()) failed_ = true;
  }

  StateView state() const override { return StateView(x_.data(), x_.size()); }
  const Eigen::MatrixXd* covariance() const override { return &P_; }
  std::string status() const override { return failed_ ? "numerical_failure" : "ok"; }
  const Innovations* innovations() const override { return &innovations_; }

 private:
  // Sensor s takes part in this period's update: a fresh sample, or a held value of a
  // send-on-delta sensor.
  bool use(std::size_t s, std::uint64_t fresh) const {
    if ((fresh >> s) & 1U) return true;
    return hold_.ever(s) && p_.send_on_delta[s];
  }

  const SodKalmanParams& p_;
  SodHold hold_;
  Eigen::VectorXd x_;
  Eigen::MatrixXd P_;
  kalman::Workspace ws_;
  std::vector<Eigen::Index> rows_;
  Innovations innovations_;
  bool failed_ = false;
};

class SodKalmanDesign final : public EstimatorDesign {
 public:
  bool is_kalman_reference() const override { return true; }
  SodKalmanDesign(SodKalmanParams p, const Model& model, double factor)
      : p_(std::move(p)), model_(model) {
    report_.method = "online";
    report_.stored_gains = 0;
    report_.extra["virtual_variance_factor"] = factor;
    report_.extra["delta"] = std::vector<double>(p_.virtual_var.size());
    for (Eigen::Index i = 0; i < p_.virtual_var.size(); ++i) {
      report_.extra["delta"][static_cast<std::size_t>(i)] =
          factor > 0 ? std::sqrt(p_.virtual_var(i) / factor) : 0.0;
    }
  }
  std::unique_ptr<Estimator> instantiate() const override {
    return std::make_unique<SodKalman>(p_, model_);
  }
  const DesignReport& report() const override { return report_; }
  std::optional<double> flops_per_period() const override {
    // Predict (2n^3 + n^2 + n: A P A' + Q, A x) and the update with all ny rows (as
    // kalman_extended: 4 n^2 ny + 2 n ny^2 + 5 ny^3 + 2 n ny + ny^2 + ny).
    const double n = static_cast<double>(p_.A.rows()), ny = static_cast<double>(p_.C.rows());
    return 2 * n * n * n + 2 * n * n + n + 4 * n * n * ny + 2 * n * ny * ny + 5 * ny * ny * ny +
           2 * n * ny + ny * ny + ny;
  }

 private:
  SodKalmanParams p_;
  const Model& model_;  // sensor layout only (the scenario outlives its designs)
  DesignReport report_;
};

const config::Keys& sod_kalman_keys() {
  using config::Key;
  static const config::Keys keys =
      config::Keys{
          Key::matrix("W")
              .optional("the plant's W")
              .help("the filter's process-noise covariance, nw x nw (PSD) or a number (x I)"),
          Key::vector("R")
              .optional("the sensors' R diagonals")
              .help("the filter's noise variances: total outputs, >= 0"),
          Key::vector("delta")
              .optional("the sensors' thresholds (0 for periodic)")
              .help("thresholds the filter assumes: total outputs, >= 0"),
          Key::number("virtual_variance_factor")
              .min(0.0)
              .noun("a factor")
              .or_default(1.0 / 3.0)
              .help("virtual-noise variance / delta^2 (1/3: delta uniform in (-D, D))"),
      } +
      initial_keys();
  return keys;
}

std::unique_ptr<EstimatorDesign> read_sod_kalman(const config::Table& t, const Model& model) {
  const config::KeyReader r(t, sod_kalman_keys());
  SodKalmanParams p;
  p.A = model.plant.A;
  stacked_outputs(model, p.C, p.R);
  Eigen::MatrixXd W = model.plant.W;
  if (r.has("W")) {
    W = r.matrix("W");
    if (W.size() == 1 && model.plant.nw() > 1)
      W = W(0, 0) * Eigen::MatrixXd::Identity(model.plant.nw(), model.plant.nw());
    config::require_shape(t, "W", W, model.plant.nw(), model.plant.nw());
    config::require_psd(t, "W", W);
  }
  p.Q = model.plant.Bw * W * model.plant.Bw.transpose();
  const Eigen::Index ny = model.total_outputs();
  if (r.has("R")) {
    const Eigen::VectorXd v = r.vector("R");
    if (v.size() != ny || !v.allFinite() || v.minCoeff() < 0.0) {
      t.fail("R", fmt::format("expected {} non-negative variances (one per output, replacing the "
                              "sensors' R), got [{}]",
                              ny, fmt::join(v.data(), v.data() + v.size(), ", ")));
    }
    p.R = v.asDiagonal();
  }
  Eigen::VectorXd delta = stacked_delta(model);
  if (r.has("delta")) {
    delta = r.vector("delta");
    if (delta.size() != ny || !delta.allFinite() || delta.minCoeff() < 0.0) {
      t.fail("delta", fmt::format("expected {} thresholds >= 0 (one per output), got [{}]", ny,
                                  fmt::join(delta.data(), delta.data() + delta.size(), ", ")));
    }
  }
  const double factor = r.number("virtual_variance_factor");
  p.virtual_var = factor * delta.cwiseProduct(delta);
  p.init = read_initial(t, model);
  for (const auto& sm : model.sensors) p.send_on_delta.push_back(sm.spec.deadband() != nullptr);
  return std::make_unique<SodKalmanDesign>(std::move(p), model, factor);
}

// No offline iteration: the model, noise covariances and the virtual noise per sensor are kept
// (the filter runs online); a few n x n products.
DesignCost sod_kalman_cost(const config::Table& /*t*/, const toml::table& /*raw*/,
                           const Model& model, const std::string& /*driver*/) {
  const double n = static_cast<double>(model.plant.n());
  const double ny = static_cast<double>(model.total_outputs());
  return {8.0 * 8.0 * (n * n + ny * ny), 10.0 * n * n * n, ""};
}

}  // namespace

void register_sod_kalman(EstimatorRegistry& registry) {
  registry.add("sod_kalman",
               "Kalman filter on held send-on-delta measurements with virtual noise (Suh et al. "
               "2007): W, R, "
               "delta (default: the sensors' thresholds), virtual_variance_factor (default 1/3)",
               sod_kalman_keys(), read_sod_kalman, sod_kalman_cost);
}

}  // namespace ncosim::est
