// estimators/kalman_extended.cc
// Time-varying Kalman filter on the delay-extended model (Dolz et al. 2014, section 2, the
// comparison "adapted from Schenato (2008)"): predict xbar and P with Abar, then update with the
// rows of the fictitious sensors delivered this period (estimators/kalman_update.h). An innovation
// covariance that is only semidefinite uses its pseudo-inverse; a non-finite innovation or
// estimate marks the run "numerical_failure".
#include <fmt/format.h>

#include <Eigen/Cholesky>
#include <bit>

#include "estimators/delay_window.h"
#include "estimators/extended_model.h"
#include "estimators/kalman_update.h"
#include "estimators/kinds.h"

namespace ncosim::est {

namespace {

class KalmanExtended final : public Estimator {
 public:
  KalmanExtended(const ExtendedModel& ext, const InitialEstimate& init)
      : ext_(ext),
        window_(ext, /*deduplicate=*/true),
        x_(ext.nb),
        P_(Eigen::MatrixXd::Zero(ext.nb, ext.nb)),
        ws_(ext.nb, ext.nmb),
        rows_(static_cast<std::size_t>(ext.nmb)) {
    // Before t = 0 the plant rests at x0 (x[-j] = x0) and every block starts at xhat0, so all
    // blocks share one error: P = (1 1') ⊗ P0.
    for (int b = 0; b <= ext.dbar; ++b) {
      x_.segment(b * ext.n, ext.n) = init.xhat0;
      for (int c = 0; c <= ext.dbar; ++c) P_.block(b * ext.n, c * ext.n, ext.n, ext.n) = init.P0;
    }
  }

  int on_packet(const Packet& p, std::int64_t k) override { return window_.accept(p, k); }

  void on_period(std::int64_t k, const PeriodInput& in) override {
    window_.advance(k);
    const Eigen::Index n = ext_.n;
    if (k > 0) {
      kalman::predict_state(ext_.A, x_, ws_);  // Abar: A on the head block, shift below
      x_.head(n) += in.drive;
      kalman::predict_covariance(ext_.A, ext_.Q, P_, ws_);
    }
    const std::uint64_t pattern = window_.pattern();
    window_.clear_pattern();
    if (pattern == 0) return;
    Eigen::Index m = 0;
    for (std::uint64_t bits = pattern; bits != 0; bits &= bits - 1) {
      const auto& f = ext_.fict[std::countr_zero(bits)];
      for (Eigen::Index r = 0; r < f.rows; ++r) rows_[m++] = f.row + r;
    }
    kalman::select(ext_.C, ext_.V, window_.values(), rows_.data(), m, ws_);
    if (!kalman::update(x_, P_, ws_, &innovations_)) {
      failed_ = true;
      return;
    }
    if (!x_.allFinite()) failed_ = true;
  }

  StateView state() const override { return StateView(x_.data(), ext_.n); }
  const Eigen::VectorXd* extended() const override { return &x_; }
  const Eigen::MatrixXd* covariance() const override { return &P_; }
  std::string status() const override { return failed_ ? "numerical_failure" : "ok"; }
  const Innovations* innovations() const override { return &innovations_; }

 private:
  const ExtendedModel& ext_;
  DelayWindow window_;
  Eigen::VectorXd x_;
  Eigen::MatrixXd P_;
  kalman::Workspace ws_;
  std::vector<Eigen::Index> rows_;
  Innovations innovations_;
  bool failed_ = false;
};

class KalmanExtendedDesign final : public EstimatorDesign {
 public:
  KalmanExtendedDesign(const Model& model, int dbar, InitialEstimate init)
      : ext_(build_extended(model, dbar)), init_(std::move(init)) {
    report_.method = "none";
    report_.extra["max_delay"] = dbar;
  }
  std::unique_ptr<Estimator> instantiate() const override {
    return std::make_unique<KalmanExtended>(ext_, init_);
  }
  const DesignReport& report() const override { return report_; }
  std::optional<double> flops_per_period() const override {
    // Dolz et al. section 2: 2nb^3 + nb^2 nw + nb nw^2 + 4 nb^2 nmb + 2 nb nmb^2 + 5 nmb^3
    //   + 2 nb^2 + nb nu + 2 nb nmb + nmb^2 + 2 nb + nmb.
    const double nb = static_cast<double>(ext_.nb), nu = static_cast<double>(ext_.nu);
    const double nw = static_cast<double>(ext_.nw), nmb = static_cast<double>(ext_.nmb);
    return 2 * nb * nb * nb + nb * nb * nw + nb * nw * nw + 4 * nb * nb * nmb + 2 * nb * nmb * nmb +
           5 * nmb * nmb * nmb + 2 * nb * nb + nb * nu + 2 * nb * nmb + nmb * nmb + 2 * nb + nmb;
  }
  Eigen::Index extended_size() const override { return ext_.nb; }
  bool is_kalman_reference() const override { return true; }

 private:
  ExtendedModel ext_;
  InitialEstimate init_;
  DesignReport report_;
};

const config::Keys& kalman_extended_keys() {
  static const config::Keys keys =
      config::Keys{max_delay_key().or_default(0).help(
          "d-bar; sensors x (max_delay + 1) <= 64 (the fictitious sensors of one period are a "
          "64-bit pattern)")} +
      initial_keys();
  return keys;
}

std::unique_ptr<EstimatorDesign> read_kalman_extended(const config::Table& t, const Model& model) {
  const config::KeyReader r(t, kalman_extended_keys());
  const int dbar = static_cast<int>(r.integer("max_delay"));
  const auto nf = static_cast<long>(model.sensors.size()) * (dbar + 1);
  if (nf > 64) {
    t.fail("max_delay",
           fmt::format("expected at most 64 fictitious sensors (sensors x (max_delay + 1)), "
                       "got {} x {} = {}",
                       model.sensors.size(), dbar + 1, nf));
  }
  return std::make_unique<KalmanExtendedDesign>(model, dbar, read_initial(t, model));
}

// The design builds the delay-extended model (n (dbar + 1) + ny dbar states) and no offline
// Riccati iteration (the filter runs its recursion online): about 4 products of that size, and
// 16 matrices of it (the model, and the covariance and workspace every run then keeps).
DesignCost kalman_extended_cost(const config::Table& t, const toml::table& raw, const Model& model,
                                const std::string& driver) {
  const double n = static_cast<double>(model.plant.n());
  const double ny = static_cast<double>(model.total_outputs());
  const std::int64_t dbar = peek_integer(raw, kalman_extended_keys().at("max_delay"));
  const double dim = n * static_cast<double>(dbar + 1) + ny * static_cast<double>(dbar);
  DesignCost c{16.0 * 8.0 * dim * dim, 4.0 * dim * dim * dim, ""};
  if (dbar > 0) c.driver = fmt::format("{} (with {})", t.key_path("max_delay"), driver);
  return c;
}

}  // namespace

void register_kalman_extended(EstimatorRegistry& registry) {
  registry.add("kalman_extended",
               "time-varying Kalman filter on the delay-extended model: max_delay (dbar)",
               kalman_extended_keys(), read_kalman_extended, kalman_extended_cost);
}

}  // namespace ncosim::est
