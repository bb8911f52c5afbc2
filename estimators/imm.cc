// estimators/imm.cc
// `imm`: interacting multiple model filter, one Kalman filter per mode of the mode model
// (estimators/mode_model.h: actuator delivery patterns with the hold/zero strategy, or the
// modes of a jump_linear plant) on the numerical core estimators/imm_filter.h (Bar-Shalom, Li
// & Kirubarajan 2001, 11.6.6). Period k: mixing and mode-matched prediction with the input sent
// at k-1, then the update with the delay-0 samples that arrived (none: priors kept, mu = cbar;
// some sensors: their rows only). Its mode estimate is argmax mu = argmax p(theta[k-1] | Y_k)
// (Moayedi et al. eq. 16 with the IMM's mode probabilities). A failed update marks the run
// "numerical_failure" and keeps the priors.
#include "estimators/imm.h"

#include <fmt/format.h>

#include <algorithm>

#include "estimators/imm_filter.h"
#include "estimators/kinds.h"
#include "estimators/mode_model.h"

namespace ncosim::est {

namespace {

std::vector<ImmMode> imm_modes(const ModeModel& mm) {
  std::vector<ImmMode> modes;
  for (int j = 0; j < mm.modes(); ++j) {
    const auto uj = static_cast<std::size_t>(j);
    modes.push_back(ImmMode{mm.A[uj], mm.B[uj], mm.Q[uj], mm.C, mm.R});
  }
  return modes;
}

class Imm final : public Estimator {
 public:
  explicit Imm(const ModeSetup& setup)
      : setup_(setup),
        filter_(imm_modes(setup.model), setup.model.transition, setup.x0, setup.P0, setup.mu0),
        meas_(setup.model.ext0),
        u_ext_(Eigen::VectorXd::Zero(setup.model.nue)) {}

  int on_packet(const Packet& p, std::int64_t k) override { return meas_.accept(p, k); }

  void on_period(std::int64_t k, const PeriodInput& in) override {
    const ModeModel& mm = setup_.model;
    if (k > 0) {
      u_ext_.head(mm.nu) = in.u;
      u_ext_.tail(mm.n) = in.drive;
      u_ext_.tail(mm.n).noalias() -= mm.Bu * in.u;  // the known re-centring drive (0 without)
      filter_.predict(u_ext_);
    }
    const Eigen::Index rows = meas_.take(k);
    if (rows == 0 || (k == 0 && !setup_.use_y0)) {
      filter_.skip_update();
    } else {
      filter_.update(meas_.values(), meas_.mask());
    }
    has_mode_ = k > 0;
  }

  StateView state() const override { return StateView(filter_.x().data(), setup_.model.n); }
  const Eigen::MatrixXd* covariance() const override { return &filter_.P(); }
  std::optional<int> mode() const override {
    if (!has_mode_) return std::nullopt;
    return filter_.most_probable_mode();
  }
  std::string status() const override {
    return filter_.status() == ImmStatus::kOk ? "ok" : "numerical_failure";
  }
  const ImmFilter& filter() const { return filter_; }

 private:
  const ModeSetup& setup_;
  ImmFilter filter_;
  CurrentMeasurement meas_;
  Eigen::VectorXd u_ext_;
  bool has_mode_ = false;
};

class ImmDesign final : public EstimatorDesign {
 public:
  explicit ImmDesign(ModeSetup setup) : setup_(std::move(setup)) {
    report_.method = "none";
    report_.stored_gains = 0;
    report_.extra["modes"] = setup_.model.modes();
  }
  std::unique_ptr<Estimator> instantiate() const override { return std::make_unique<Imm>(setup_); }
  const DesignReport& report() const override { return report_; }
  std::optional<double> flops_per_period() const override {
    const ModeModel& mm = setup_.model;
    const double s = mm.modes(), na = static_cast<double>(mm.na), m = static_cast<double>(mm.m);
    // s Kalman filters; mixing: cbar (2s²), weights (2s²), mixed means (2s² na) and covariances
    // (s² (3na² + 2na)); likelihoods (s (m + 4)); combination (s (3na² + 4na)).
    return s * kalman_flops(na, static_cast<double>(mm.nue), m) + 4 * s * s + 2 * s * s * na +
           s * s * (3 * na * na + 2 * na) + s * (m + 4) + s * (3 * na * na + 4 * na);
  }

 private:
  ModeSetup setup_;
  DesignReport report_;
};

std::unique_ptr<EstimatorDesign> read_imm(const config::Table& t, const Model& model) {
  return std::make_unique<ImmDesign>(read_mode_setup(config::KeyReader(t, mode_keys()), model));
}

// The mode model of every mode (mode_model.h: A, B, W per mode and the transition matrix), a
// few n x n products per mode, no iteration.
DesignCost imm_cost(const config::Table& /*t*/, const toml::table& /*raw*/, const Model& model,
                    const std::string& /*driver*/) {
  const double n = static_cast<double>(model.plant.n());
  const double modes = std::max(1.0, static_cast<double>(model.mode_count()));
  return {modes * 8.0 * 8.0 * n * n + 8.0 * modes * modes, modes * 10.0 * n * n * n, ""};
}

}  // namespace

const ImmFilter* imm_filter_of(const Estimator& estimator) {
  const auto* imm = dynamic_cast<const Imm*>(&estimator);
  return imm == nullptr ? nullptr : &imm->filter();
}

void register_imm(EstimatorRegistry& registry) {
  registry.add(
      "imm",
      "interacting multiple model filter over the actuator delivery patterns (hold/zero) or "
      "a jump_linear plant's modes: mode_prior, transition, xhat0, P0, use_y0",
      mode_keys(), read_imm, imm_cost);
}

}  // namespace ncosim::est
