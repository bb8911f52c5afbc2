// estimators/mode_io.cc
// `mode_io`: Algorithm 1 of Moayedi et al. (input-output mode estimation). The plant
// (A, Bu, C) in ARMAX form by Cayley-Hamilton: with a_1..a_n the characteristic polynomial of A
// (a_0 = 1) and M_1 = I, M_{j+1} = A M_j + a_j I,
//   y[k] + sum_i a_i y[k-i] = sum_j C M_j (Bu uhat[k-j] + d[k-j]) + e[k]      (eq. 15),
// e[k] = sum_i a_i v[k-i] + sum_j C M_j w[k-j], d the known re-centring drive (0 without). For
// (A, Bu, C = I) this is the paper's a = (-tr A, det A), b1 = Bu, b2 = (A - tr(A) I) Bu, c = a.
// Period k >= 1: yhat_j = -sum_i a_i y[k-i] + C M_1 (Bu uhat_j[k-1] + d) + sum_{l>=2} C M_l
// (Bu uhat[k-l] + d) with uhat_j[k-1] = Gamma(j) u[k-1] + (I - Gamma(j)) uhat[k-2] on hold
// channels (0 on zero channels) and uhat[k-l] the applied inputs implied by the previous mode
// estimates (eq. 22); Sigma = sum_i a_i^2 R + sum_j C M_j Q M_j' C' (eq. 23 with the exact
// coefficients); p(theta[k-1] | Y_k) by eq. 19; thetahat = argmax (16); then the Kalman filter
// (18) with thetahat (step 6). A missing output enters the lags as C xhat[k|k]. Start-up (the paper
// does not say): while a lag would precede period 0 (k < n), startup = "state" (default) uses the
// filter's one-step state-space likelihoods (eqs. 24-25, as Algorithm 2), "prior_mean" takes the
// unknown lags as the prior mean (y[-i] = C xhat0, uhat[-l] = the held part of xhat0), "skip" uses
// no likelihood (p = E). Needs actuator modes (not a jump_linear plant).
#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "estimators/kalman_update.h"
#include "estimators/kinds.h"
#include "estimators/mode_model.h"

namespace ncosim::est {

namespace {

struct IoModel {
  Eigen::VectorXd a;               // a_0 .. a_n
  std::vector<Eigen::MatrixXd> G;  // G_j = C M_j, j = 1..n (index j-1)
  Eigen::MatrixXd Sigma;           // eq. 23
  enum class Startup { kState, kPriorMean, kSkip } startup = Startup::kState;
};

// Characteristic polynomial det(lambda I - A) = sum_i a_i lambda^(n-i), a_0 = 1
// (Faddeev-LeVerrier).
Eigen::VectorXd char_poly(const Eigen::MatrixXd& A) {
  const Eigen::Index n = A.rows();
  Eigen::VectorXd a = Eigen::VectorXd::Zero(n + 1);
  a(0) = 1.0;
  Eigen::MatrixXd M = Eigen::MatrixXd::Zero(n, n);
  for (Eigen::Index k = 1; k <= n; ++k) {
    M = A * M + a(k - 1) * Eigen::MatrixXd::Identity(n, n);
    a(k) = -(A * M).trace() / static_cast<double>(k);
  }
  return a;
}

IoModel build_io(const Model& model, const ModeModel& mm) {
  IoModel io;
  const auto& p = model.plant;
  const Eigen::Index n = p.n();
  io.a = char_poly(p.A);
  const Eigen::MatrixXd C = mm.ext0.C;
  Eigen::MatrixXd M = Eigen::MatrixXd::Identity(n, n);
  const Eigen::MatrixXd Q = p.Bw * p.W * p.Bw.transpose();
  io.Sigma = Eigen::MatrixXd::Zero(mm.m, mm.m);
  for (Eigen::Index i = 0; i <= n; ++i) io.Sigma += io.a(i) * io.a(i) * mm.R;
  for (Eigen::Index j = 1; j <= n; ++j) {
    io.G.push_back(C * M);
    io.Sigma += io.G.back() * Q * io.G.back().transpose();
    M = p.A * M + io.a(j) * Eigen::MatrixXd::Identity(n, n);
  }
  return io;
}

// The last n vectors, newest first, in preallocated storage (push() overwrites the oldest).
class Lags {
 public:
  void assign(Eigen::Index n, const Eigen::VectorXd& value) {
    ring_.assign(static_cast<std::size_t>(n), value);
    head_ = 0;
  }
  // Lag i (0: the newest).
  const Eigen::VectorXd& operator[](std::size_t i) const {
    return ring_[(head_ + i) % ring_.size()];
  }
  // Makes the oldest the newest and returns it for the caller to overwrite.
  Eigen::VectorXd& push() {
    head_ = (head_ + ring_.size() - 1) % ring_.size();
    return ring_[head_];
  }

 private:
  std::vector<Eigen::VectorXd> ring_;
  std::size_t head_ = 0;
};

class ModeIo final : public Estimator {
 public:
  ModeIo(const ModeSetup& setup, const IoModel& io)
      : setup_(setup),
        io_(io),
        kf_(setup.model, setup.x0, setup.P0),
        meas_(setup.model.ext0),
        p_(setup.mu0),
        e_(setup.mu0.size()),
        loglik_(setup.mu0.size()),
        u_ext_(Eigen::VectorXd::Zero(setup.model.nue)),
        uhat_(Eigen::VectorXd::Zero(setup.model.nu)),
        g_(Eigen::VectorXd::Zero(setup.model.n)),
        ybar_(Eigen::VectorXd::Zero(setup.model.m)),
        yj_(Eigen::VectorXd::Zero(setup.model.m)),
        ys_(Eigen::VectorXd::Zero(setup.model.m)),
        sigma_(0, setup.model.m),
        x_none_(0),
        P_none_(0, 0) {
    const ModeModel& mm = setup.model;
    const Eigen::Index n = mm.n;
    // Lags before period 0: the prior mean.
    const Eigen::VectorXd y_prior = mm.ext0.C * setup.x0.head(n);
    uhat_prev_ = Eigen::VectorXd::Zero(mm.nu);
    for (std::size_t c = 0; c < mm.hold.size(); ++c) {
      uhat_prev_(mm.hold[c]) = setup.x0(n + static_cast<Eigen::Index>(c));
    }
    const Eigen::VectorXd g_prior = mm.Bu * uhat_prev_;
    ylag_.assign(n, y_prior);
    glag_.assign(n, g_prior);
  }

  int on_packet(const Packet& p, std::int64_t k) override { return meas_.accept(p, k); }

  void on_period(std::int64_t k, const PeriodInput& in) override {
    const ModeModel& mm = setup_.model;
    const Eigen::Index n = mm.n;
    const int r = mm.channels;
    meas_.take(k);
    kf_.select(meas_.mask());
    if (k > 0) {
      u_ext_.head(mm.nu) = in.u;
      u_ext_.tail(n) = in.drive;
      u_ext_.tail(n).noalias() -= mm.Bu * in.u;
      const auto d = u_ext_.tail(n);
      e_.noalias() = mm.transition.transpose() * p_;
      // ybar: every term of yhat_j but the one of uhat[k-1] (ylag_[i-1] = y[k-i], glag_[l-1] =
      // g[k-l]).
      ybar_.setZero();
      for (Eigen::Index i = 1; i <= n; ++i)
        ybar_ -= io_.a(i) * ylag_[static_cast<std::size_t>(i - 1)];
      for (Eigen::Index l = 2; l <= n; ++l)
        ybar_.noalias() +=
            io_.G[static_cast<std::size_t>(l - 1)] * glag_[static_cast<std::size_t>(l - 2)];
      const bool lags_known = k >= n;
      const Eigen::Index rows = kf_.rows();
      if (rows > 0 && !lags_known && io_.startup == IoModel::Startup::kState) {
        // Until every lag is measured: the one-step state-space prediction of the filter.
        for (int j = 0; j < mm.modes(); ++j)
          loglik_(j) = kf_.predicted_loglik(j, u_ext_, meas_.values());
        bayes_log(e_, loglik_, p_);
      } else if (rows > 0 && (lags_known || io_.startup == IoModel::Startup::kPriorMean)) {
        // log N(y; yhat_j, Sigma) of the delivered rows: the kernel with an empty state.
        kf_.selected(meas_.values(), ys_);
        const auto& idx = kf_.selected_rows();
        for (Eigen::Index a = 0; a < rows; ++a) {
          for (Eigen::Index b = 0; b < rows; ++b) sigma_.R(a, b) = io_.Sigma(idx[a], idx[b]);
        }
        sigma_.m = rows;
        bool ok = true;
        for (int j = 0; j < mm.modes() && ok; ++j) {
          yj_ = ybar_;
          yj_.noalias() += io_.G[0] * applied_drive(j, in.u, d, r);
          for (Eigen::Index a = 0; a < rows; ++a) sigma_.y(a) = ys_(a) - yj_(idx[a]);
          ok = kalman::factor(x_none_, P_none_, sigma_) == kalman::Factor::kOk;
          loglik_(j) = sigma_.log_likelihood();
        }
        if (ok) {
          bayes_log(e_, loglik_, p_);
        } else {
          p_ = e_;
        }
      } else {
        p_ = e_;
      }
      Eigen::Index best = 0;
      p_.maxCoeff(&best);
      mode_ = static_cast<int>(best);
      // uhat[k-1] and g[k-1] implied by the estimate (eq. 22b).
      const Eigen::VectorXd& g = applied_drive(mode_, in.u, d, r);
      uhat_prev_ = uhat_;
      glag_.push() = g;
      kf_.predict(mode_, u_ext_);
    }
    if (k > 0 || setup_.use_y0) kf_.update(meas_.values());
    // y[k] into the lags: measured rows, the filter's C xhat[k|k] for the rest.
    Eigen::VectorXd& yk = ylag_.push();
    yk.noalias() = mm.ext0.C * kf_.x().head(n);
    const Eigen::VectorXd& mask = meas_.mask();
    for (Eigen::Index q = 0; q < mask.size(); ++q) {
      if (mask(q) != 0.0) yk(q) = meas_.values()(q);
    }
  }

  StateView state() const override { return StateView(kf_.x().data(), setup_.model.n); }
  const Eigen::MatrixXd* covariance() const override { return &kf_.P(); }
  std::optional<int> mode() const override {
    if (mode_ < 0) return std::nullopt;
    return mode_;
  }
  std::string status() const override { return kf_.failed() ? "numerical_failure" : "ok"; }

 private:
  // Bu uhat_j[k-1] + d under mode j (in g_); leaves uhat_j[k-1] in uhat_.
  const Eigen::VectorXd& applied_drive(int j, const Eigen::VectorXd& u,
                                       const Eigen::Ref<const Eigen::VectorXd>& d, int r) {
    const ModeModel& mm = setup_.model;
    uhat_.setZero();
    for (int i = 0; i < r; ++i) {
      if (models::channel_delivered(j, i, r)) {
        uhat_(i) = u(i);
      } else if (std::find(mm.hold.begin(), mm.hold.end(), i) != mm.hold.end()) {
        uhat_(i) = uhat_prev_(i);
      }
    }
    g_.noalias() = mm.Bu * uhat_;
    g_ += d;
    return g_;
  }

  const ModeSetup& setup_;
  const IoModel& io_;
  ModeKalman kf_;
  CurrentMeasurement meas_;
  Eigen::VectorXd p_, e_, loglik_, u_ext_;
  Eigen::VectorXd uhat_, uhat_prev_;  // applied input estimates uhat[k-1], uhat[k-2]
  Eigen::VectorXd g_, ybar_, yj_, ys_;
  kalman::Workspace sigma_;  // the Sigma factor of the likelihoods (no state)
  Eigen::VectorXd x_none_;
  Eigen::MatrixXd P_none_;
  Lags ylag_, glag_;  // y[k-1..k-n]; Bu uhat + d at k-1..k-n
  int mode_ = -1;
};

class ModeIoDesign final : public EstimatorDesign {
 public:
  ModeIoDesign(ModeSetup setup, IoModel io) : setup_(std::move(setup)), io_(std::move(io)) {
    report_.method = "none";
    report_.stored_gains = 0;
    report_.extra["modes"] = setup_.model.modes();
    report_.extra["armax_a"] = std::vector<double>(io_.a.data(), io_.a.data() + io_.a.size());
  }
  std::unique_ptr<Estimator> instantiate() const override {
    return std::make_unique<ModeIo>(setup_, io_);
  }
  const DesignReport& report() const override { return report_; }
  void set_extra(const std::string& key, const std::string& value) { report_.extra[key] = value; }
  std::optional<double> flops_per_period() const override {
    const ModeModel& mm = setup_.model;
    const double s = mm.modes(), na = static_cast<double>(mm.na), m = static_cast<double>(mm.m);
    const double n = static_cast<double>(mm.n), nu = static_cast<double>(mm.nu);
    // The Kalman filter (step 6); the mode-free part of yhat (2n m + 2(n-1)(m n + n nu)); per mode
    // the applied drive and its output (2n nu + 2m n + m) and the likelihood (m² + 2m + 4); the
    // Sigma factor (m³/3); the Bayes step (2s² + 4s).
    return kalman_flops(na, static_cast<double>(mm.nue), m) + 2 * n * m +
           2 * (n - 1) * (m * n + n * nu) + s * (2 * n * nu + 2 * m * n + m + m * m + 2 * m + 4) +
           m * m * m / 3 + 2 * s * s + 4 * s;
  }

 private:
  ModeSetup setup_;
  IoModel io_;
  DesignReport report_;
};

const config::Keys& mode_io_keys() {
  static const config::Keys keys =
      mode_keys() + config::Keys{config::Key::choice("startup", {"state", "prior_mean", "skip"})
                                     .or_default("state")
                                     .help("while a lag of the ARMAX form precedes period 0: the "
                                           "filter's state-space likelihoods (as Algorithm 2), the "
                                           "prior mean for the unknown outputs and inputs, or no "
                                           "likelihood (the chain's prediction)")};
  return keys;
}

std::unique_ptr<EstimatorDesign> read_mode_io(const config::Table& t, const Model& model) {
  const config::KeyReader r(t, mode_io_keys());
  if (!model.plant.modes.empty()) {
    t.fail_here(
        "expected actuator modes ([[actuator]] tables); mode_io does not model a jump_linear "
        "plant");
  }
  ModeSetup setup = read_mode_setup(r, model);
  IoModel io = build_io(model, setup.model);
  const std::string startup = r.string("startup");
  io.startup = startup == "state"        ? IoModel::Startup::kState
               : startup == "prior_mean" ? IoModel::Startup::kPriorMean
                                         : IoModel::Startup::kSkip;
  auto design = std::make_unique<ModeIoDesign>(std::move(setup), std::move(io));
  design->set_extra("startup", startup);
  return design;
}

// The mode model of every mode and, per mode, the ARMAX form by Cayley-Hamilton (the
// characteristic polynomial and n powers of A: about 2 n products of n x n matrices per mode).
DesignCost mode_io_cost(const config::Table& /*t*/, const toml::table& /*raw*/, const Model& model,
                        const std::string& /*driver*/) {
  const double n = static_cast<double>(model.plant.n());
  const double modes = std::max(1.0, static_cast<double>(model.mode_count()));
  return {modes * 8.0 * 8.0 * n * n * 2.0 + 8.0 * modes * modes,
          modes * (30.0 + 4.0 * n) * n * n * n, ""};
}

}  // namespace

void register_mode_io(EstimatorRegistry& registry) {
  registry.add(
      "mode_io",
      "Algorithm 1 of Moayedi et al.: mode by the input-output (ARMAX) form, then one Kalman "
      "filter: mode_prior, transition, startup, xhat0, P0, use_y0",
      mode_io_keys(), read_mode_io, mode_io_cost);
}

}  // namespace ncosim::est
