// estimators/mode_ss.cc
// `mode_ss`: Algorithm 2 of Moayedi et al. (state-space mode estimation, one Kalman filter).
// Period k >= 1: E_j = sum_l q_lj p(theta[k-2] = l | Y_{k-1}) (eq. 19); for every mode j the
// one-step prediction of y[k] from xhat[k-1|k-1], P[k-1|k-1] (eqs. 24-25), its Gaussian
// likelihood (21a); p(theta[k-1] = j | Y_k) ∝ E_j p(y_k | j) in the log domain; thetahat[k-1] =
// argmax (16); then the Kalman filter (18) with A(thetahat), B(thetahat). Rows of sensors that
// did not deliver are left out of the likelihoods and the update; with none, p = E. A failed
// Cholesky marks the run "numerical_failure" (the prediction is kept).
#include <fmt/format.h>

#include <algorithm>

#include "estimators/kinds.h"
#include "estimators/mode_model.h"

namespace ncosim::est {

namespace {

class ModeSs final : public Estimator {
 public:
  explicit ModeSs(const ModeSetup& setup)
      : setup_(setup),
        kf_(setup.model, setup.x0, setup.P0),
        meas_(setup.model.ext0),
        p_(setup.mu0),
        e_(setup.mu0.size()),
        loglik_(setup.mu0.size()),
        u_ext_(Eigen::VectorXd::Zero(setup.model.nue)) {}

  int on_packet(const Packet& p, std::int64_t k) override { return meas_.accept(p, k); }

  void on_period(std::int64_t k, const PeriodInput& in) override {
    const ModeModel& mm = setup_.model;
    meas_.take(k);
    kf_.select(meas_.mask());
    if (k == 0) {
      if (setup_.use_y0) kf_.update(meas_.values());
      return;
    }
    u_ext_.head(mm.nu) = in.u;
    u_ext_.tail(mm.n) = in.drive;
    u_ext_.tail(mm.n).noalias() -= mm.Bu * in.u;
    e_.noalias() = mm.transition.transpose() * p_;
    if (kf_.rows() > 0) {
      for (int j = 0; j < mm.modes(); ++j)
        loglik_(j) = kf_.predicted_loglik(j, u_ext_, meas_.values());
      bayes_log(e_, loglik_, p_);
    } else {
      p_ = e_;
    }
    Eigen::Index best = 0;
    p_.maxCoeff(&best);
    mode_ = static_cast<int>(best);
    kf_.predict(mode_, u_ext_);
    kf_.update(meas_.values());
  }

  StateView state() const override { return StateView(kf_.x().data(), setup_.model.n); }
  const Eigen::MatrixXd* covariance() const override { return &kf_.P(); }
  std::optional<int> mode() const override {
    if (mode_ < 0) return std::nullopt;
    return mode_;
  }
  std::string status() const override { return kf_.failed() ? "numerical_failure" : "ok"; }

 private:
  const ModeSetup& setup_;
  ModeKalman kf_;
  CurrentMeasurement meas_;
  Eigen::VectorXd p_, e_, loglik_, u_ext_;
  int mode_ = -1;
};

class ModeSsDesign final : public EstimatorDesign {
 public:
  explicit ModeSsDesign(ModeSetup setup) : setup_(std::move(setup)) {
    report_.method = "none";
    report_.stored_gains = 0;
    report_.extra["modes"] = setup_.model.modes();
  }
  std::unique_ptr<Estimator> instantiate() const override {
    return std::make_unique<ModeSs>(setup_);
  }
  const DesignReport& report() const override { return report_; }
  std::optional<double> flops_per_period() const override {
    const ModeModel& mm = setup_.model;
    const double s = mm.modes(), na = static_cast<double>(mm.na), m = static_cast<double>(mm.m);
    const double nue = static_cast<double>(mm.nue);
    // One Kalman filter; per mode the predicted output and covariance (eqs. 24-25: 2na² + 2na nue
    // + 4na³ + na² + 2m na² + 2m² na + m²), Cholesky, solve and log-likelihood (m³/3 + m² + 2m +
    // 4); the Bayes step (2s² + 4s).
    return kalman_flops(na, nue, m) +
           s * (2 * na * na + 2 * na * nue + 4 * na * na * na + na * na + 2 * m * na * na +
                2 * m * m * na + m * m + m * m * m / 3 + m * m + 2 * m + 4) +
           2 * s * s + 4 * s;
  }

 private:
  ModeSetup setup_;
  DesignReport report_;
};

std::unique_ptr<EstimatorDesign> read_mode_ss(const config::Table& t, const Model& model) {
  return std::make_unique<ModeSsDesign>(read_mode_setup(config::KeyReader(t, mode_keys()), model));
}

// The mode model of every mode (mode_model.h: A, B, W per mode and the transition matrix), a
// few n x n products per mode, no iteration.
DesignCost mode_ss_cost(const config::Table& /*t*/, const toml::table& /*raw*/, const Model& model,
                        const std::string& /*driver*/) {
  const double n = static_cast<double>(model.plant.n());
  const double modes = std::max(1.0, static_cast<double>(model.mode_count()));
  return {modes * 8.0 * 8.0 * n * n + 8.0 * modes * modes, modes * 10.0 * n * n * n, ""};
}

}  // namespace

void register_mode_ss(EstimatorRegistry& registry) {
  registry.add(
      "mode_ss",
      "Algorithm 2 of Moayedi et al.: mode by one-step state-space likelihoods, one Kalman "
      "filter: mode_prior, transition, xhat0, P0, use_y0",
      mode_keys(), read_mode_ss, mode_ss_cost);
}

}  // namespace ncosim::est
