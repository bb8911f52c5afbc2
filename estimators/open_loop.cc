// estimators/open_loop.cc
// Open-loop prediction xhat[k] = A xhat[k-1] + (known input): ignores every packet. The floor
// every estimator must beat. With max_delay it also reports the delay-extended estimate.
#include <fmt/format.h>

#include "estimators/kinds.h"

namespace ncosim::est {

namespace {

class OpenLoop final : public Estimator {
 public:
  OpenLoop(const Eigen::MatrixXd& A, const Eigen::VectorXd& xhat0, int dbar)
      : A_(A),
        n_(A.rows()),
        dbar_(dbar),
        x_(A.rows() * (dbar < 0 ? 1 : dbar + 1)),
        head_(A.rows()) {
    for (Eigen::Index b = 0; b < x_.size() / n_; ++b) x_.segment(b * n_, n_) = xhat0;
  }
  int on_packet(const Packet&, std::int64_t) override { return 0; }
  void on_period(std::int64_t k, const PeriodInput& in) override {
    if (k == 0) return;
    head_.noalias() = A_.lazyProduct(x_.head(n_));  // lazy: small sizes
    for (Eigen::Index b = x_.size() / n_ - 1; b >= 1; --b)
      x_.segment(b * n_, n_) = x_.segment((b - 1) * n_, n_);
    x_.head(n_) = head_ + in.drive;
  }
  StateView state() const override { return StateView(x_.data(), n_); }
  const Eigen::VectorXd* extended() const override { return dbar_ < 0 ? nullptr : &x_; }

 private:
  const Eigen::MatrixXd& A_;
  Eigen::Index n_;
  int dbar_;
  Eigen::VectorXd x_;
  Eigen::VectorXd head_;
};

class OpenLoopDesign final : public EstimatorDesign {
 public:
  OpenLoopDesign(const Model& model, int dbar, Eigen::VectorXd xhat0)
      : A_(model.plant.A), nu_(model.plant.nu()), dbar_(dbar), xhat0_(std::move(xhat0)) {
    report_.method = "none";
    report_.stored_gains = 0;
    if (dbar >= 0) report_.extra["max_delay"] = dbar;
  }
  std::unique_ptr<Estimator> instantiate() const override {
    return std::make_unique<OpenLoop>(A_, xhat0_, dbar_);
  }
  const DesignReport& report() const override { return report_; }
  std::optional<double> flops_per_period() const override {
    const double n = static_cast<double>(A_.rows());
    return n * n + n * static_cast<double>(nu_);  // A xhat + Bu u (as the jump count, no update)
  }
  Eigen::Index extended_size() const override { return dbar_ < 0 ? 0 : A_.rows() * (dbar_ + 1); }

 private:
  Eigen::MatrixXd A_;
  Eigen::Index nu_;
  int dbar_;
  Eigen::VectorXd xhat0_;
  DesignReport report_;
};

const config::Keys& open_loop_keys() {
  static const config::Keys keys =
      config::Keys{max_delay_key().optional("none").help(
          "when given, it also keeps the delay-extended estimate, so that mse_ext "
          "is reported")} +
      initial_keys();
  return keys;
}

std::unique_ptr<EstimatorDesign> read_open_loop(const config::Table& t, const Model& model) {
  const auto d = config::KeyReader(t, open_loop_keys()).opt_integer("max_delay");
  const int dbar = d ? static_cast<int>(*d) : -1;
  InitialEstimate init = read_initial(t, model);
  return std::make_unique<OpenLoopDesign>(model, dbar, std::move(init.xhat0));
}

// No design: the initial estimate and the model kept (a few n x n matrices).
DesignCost open_loop_cost(const config::Table& /*t*/, const toml::table& /*raw*/,
                          const Model& model, const std::string& /*driver*/) {
  const double n = static_cast<double>(model.plant.n());
  return {4.0 * 8.0 * n * n, 2.0 * n * n, ""};
}

}  // namespace

void register_open_loop(EstimatorRegistry& registry) {
  registry.add("open_loop",
               "open-loop prediction, ignores every packet (the floor): max_delay (optional, for "
               "mse_ext)",
               open_loop_keys(), read_open_loop, open_loop_cost);
}

}  // namespace ncosim::est
