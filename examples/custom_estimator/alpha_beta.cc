// alpha_beta.cc — a new estimator kind: the alpha-beta tracker (a fixed-gain observer of
// position and velocity), for a 2-state plant x = [position; velocity] and one sensor of the
// position. Period k: predict x = A x + drive with the plant's A, then, if the sample of period
// k arrived, correct with r = y - C x: position += alpha r, velocity += (beta / T) r.
// Keys: alpha in (0, 1], beta in (0, 2) (defaults 0.5, 0.1), xhat0 (default: the plant's x0).
#include <fmt/format.h>

#include "kinds.h"

namespace {

using ncosim::est::Estimator;
using ncosim::est::EstimatorDesign;
using ncosim::est::Model;
using ncosim::est::Packet;
using ncosim::est::PeriodInput;

struct Gains {
  Eigen::Matrix2d A;
  Eigen::RowVector2d C;
  Eigen::Vector2d K;  // [alpha; beta / T]
  Eigen::Vector2d x0;
};

class AlphaBeta final : public Estimator {
 public:
  explicit AlphaBeta(const Gains& g) : g_(g), x_(g.x0) {}

  // Only the newest sample of the current period is used (a fixed-gain filter has no model of
  // delayed samples); returns 1 when it is new.
  int on_packet(const Packet& p, std::int64_t k) override {
    if (p.count == 0 || p.stamps[0] != k || have_ == k) return 0;
    y_ = p.values(0);
    have_ = k;
    return 1;
  }

  // Fixed-size Eigen types only: nothing is allocated per period.
  void on_period(std::int64_t k, const PeriodInput& in) override {
    if (k > 0) x_ = g_.A * x_ + in.drive.head<2>();
    if (have_ == k) x_ += g_.K * (y_ - g_.C.dot(x_));
  }

  StateView state() const override { return StateView(x_.data(), 2); }

 private:
  const Gains& g_;
  Eigen::Vector2d x_;
  double y_ = 0.0;
  std::int64_t have_ = -1;
};

class AlphaBetaDesign final : public EstimatorDesign {
 public:
  AlphaBetaDesign(Gains g, double alpha, double beta) : g_(std::move(g)) {
    report_.method = "none";
    report_.extra["alpha"] = alpha;
    report_.extra["beta"] = beta;
  }
  std::unique_ptr<Estimator> instantiate() const override {
    return std::make_unique<AlphaBeta>(g_);
  }
  const ncosim::est::DesignReport& report() const override { return report_; }
  // Predict (A x: 6, + drive: 2) and correct (C x: 3, residual: 1, K r and add: 4).
  std::optional<double> flops_per_period() const override { return 16.0; }

 private:
  Gains g_;
  ncosim::est::DesignReport report_;
};

// The keys, declared as data (config/keys.h): the reader gets its values through them, and
// `ncosim list --keys`, the docs and `ncosim schema` show them. Defaults and ranges live here only.
const ncosim::config::Keys& alpha_beta_keys() {
  using ncosim::config::Key;
  static const ncosim::config::Keys keys =
      ncosim::config::Keys{
          Key::number("alpha").above(0.0).max(1.0).noun("a gain").or_default(0.5).help(
              "position gain"),
          Key::number("beta").above(0.0).below(2.0).noun("a gain").or_default(0.1).help(
              "velocity gain (divided by the period)"),
      } +
      ncosim::est::initial_keys();  // xhat0, P0 (read by read_initial)
  return keys;
}

std::unique_ptr<EstimatorDesign> read_alpha_beta(const ncosim::config::Table& t,
                                                 const Model& model) {
  if (model.plant.n() != 2 || model.sensors.size() != 1 || model.sensors[0].spec.ny() != 1) {
    t.fail_here(fmt::format(
        "expected a 2-state plant and one sensor with one output, got {} states and {} sensors",
        model.plant.n(), model.sensors.size()));
  }
  const ncosim::config::KeyReader r(t, alpha_beta_keys());
  const double alpha = r.number("alpha"), beta = r.number("beta");
  Gains g;
  g.A = model.plant.A;
  g.C = model.sensors[0].spec.C;
  g.K << alpha, beta / model.period;
  g.x0 = ncosim::est::read_initial(t, model).xhat0;
  return std::make_unique<AlphaBetaDesign>(std::move(g), alpha, beta);
}

// The design's cost before it starts (optional; without it ncosim assumes a Riccati iteration on
// the plant state): it copies A, C and the gains, a few n x n matrices and no iteration.
ncosim::est::DesignCost alpha_beta_cost(const ncosim::config::Table& /*t*/,
                                        const toml::table& /*raw*/, const ncosim::est::Model& model,
                                        const std::string& /*state_driver*/) {
  const double n = static_cast<double>(model.plant.n());
  return {4.0 * 8.0 * n * n, 4.0 * n * n, ""};
}

}  // namespace

void register_alpha_beta(ncosim::est::EstimatorRegistry& registry) {
  registry.add(
      "alpha_beta",
      "alpha-beta tracker of position and velocity (example extension): alpha, beta, xhat0",
      alpha_beta_keys(), read_alpha_beta, alpha_beta_cost);
}
