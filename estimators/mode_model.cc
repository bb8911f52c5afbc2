// estimators/mode_model.cc — mode matrices, transition matrix, initial values of the mode
// estimators.
#include "estimators/mode_model.h"

#include <fmt/format.h>

#include <bit>
#include <cmath>
#include <limits>

namespace ncosim::est {

namespace {

// The modes of a plant without its own: one per pattern j of delivered input channels (r
// channels, 2^r modes), a channel that holds on loss keeping its last value as a state.
void add_loss_modes(ModeModel& mm, const Model& model, const Eigen::MatrixXd& E) {
  const auto& p = model.plant;
  const Eigen::Index n = mm.n, h = static_cast<Eigen::Index>(mm.hold.size());
  const int r = mm.channels;
  const int s = r > 0 ? 1 << r : 1;
  Eigen::MatrixXd Q = Eigen::MatrixXd::Zero(mm.na, mm.na);
  Q.topLeftCorner(n, n) = p.Bw * p.W * p.Bw.transpose();
  for (int j = 0; j < s; ++j) {
    Eigen::MatrixXd A = Eigen::MatrixXd::Zero(mm.na, mm.na);
    Eigen::MatrixXd B = Eigen::MatrixXd::Zero(mm.na, mm.nue);
    A.topLeftCorner(n, n) = p.A;
    B.rightCols(n) = E;
    for (int i = 0; i < r; ++i) {
      const bool delivered = models::channel_delivered(j, i, r);
      if (delivered) B.block(0, i, n, 1) = p.Bu.col(i);
    }
    for (Eigen::Index c = 0; c < h; ++c) {
      const int i = mm.hold[static_cast<std::size_t>(c)];
      if (models::channel_delivered(j, i, r)) {
        B(n + c, i) = 1.0;  // the delivered value is the new held one
      } else {
        A.block(0, n + c, n, 1) = p.Bu.col(i);  // the held value is applied again
        A(n + c, n + c) = 1.0;
      }
    }
    mm.A.push_back(std::move(A));
    mm.B.push_back(std::move(B));
    mm.Q.push_back(Q);
  }
}

// Independent links (Moayedi et al., Remark 1, eq. 26): Kronecker product of the on-time
// chains, channel 0 the most significant factor (the mode numbering).
Eigen::MatrixXd loss_transition(const Model& model, int channels) {
  Eigen::MatrixXd T = Eigen::MatrixXd::Ones(1, 1);
  for (int i = 0; i < channels; ++i) {
    const models::Link* link = model.actuators[static_cast<std::size_t>(i)].link;
    Eigen::Matrix2d c;
    if (link == nullptr) {
      c << 1.0, 0.0, 1.0, 0.0;
    } else {
      c = link->on_time_chain();
    }
    Eigen::MatrixXd K(T.rows() * 2, T.cols() * 2);
    for (Eigen::Index a = 0; a < T.rows(); ++a) {
      for (Eigen::Index b = 0; b < T.cols(); ++b) K.block(2 * a, 2 * b, 2, 2) = T(a, b) * c;
    }
    T = std::move(K);
  }
  return T;
}

ModeModel build(const Model& model) {
  ModeModel mm;
  const auto& p = model.plant;
  mm.n = p.n();
  mm.nu = p.nu();
  mm.nue = mm.nu + mm.n;
  mm.Bu = p.Bu;
  mm.ext0 = build_extended(model, 0);
  mm.m = mm.ext0.nmb;
  mm.channels = static_cast<int>(model.actuators.size());
  for (int i = 0; i < mm.channels; ++i) {
    if (model.actuators[static_cast<std::size_t>(i)].spec.on_loss ==
        models::ActuatorSpec::OnLoss::kHold) {
      mm.hold.push_back(i);
    }
  }
  const Eigen::Index n = mm.n, h = static_cast<Eigen::Index>(mm.hold.size());
  mm.na = n + h;
  mm.C = Eigen::MatrixXd::Zero(mm.m, mm.na);
  mm.C.leftCols(n) = mm.ext0.C;
  mm.R = mm.ext0.V;
  // The known re-centring drive enters the plant state directly.
  Eigen::MatrixXd E = Eigen::MatrixXd::Zero(mm.na, n);
  E.topRows(n).setIdentity();
  if (!p.modes.empty()) {
    for (const auto& pm : p.modes) {
      mm.A.push_back(pm.A);
      Eigen::MatrixXd B(n, mm.nue);
      B << pm.Bu, E;
      mm.B.push_back(std::move(B));
      mm.Q.push_back(pm.Bw * pm.W * pm.Bw.transpose());
    }
    mm.transition = p.mode_transition;
  } else {
    add_loss_modes(mm, model, E);
    mm.transition = loss_transition(model, mm.channels);
  }
  return mm;
}

}  // namespace

const config::Keys& mode_keys() {
  using config::Key;
  static const config::Keys keys{
      Key::vector("xhat0")
          .optional("the plant's x0, held inputs at the actuators' u0")
          .help("the initial estimate, the prior of period 0: n entries (held inputs from u0), n "
                "+ (hold channels), or n + r (one per actuator; entries of zero channels are "
                "ignored)"),
      Key::matrix("P0").optional("zeros").help(
          "its covariance, of the same sizes as xhat0 (size n: the held inputs get covariance "
          "0)"),
      Key::choice("mode_prior", {"uniform", "stationary"})
          .or_default("uniform")
          .help("p(theta[-1] = j | Y0): 1/s each (the paper), or the chain's stationary law"),
      Key::matrix("transition")
          .optional("derived from the links, or the jump_linear plant's")
          .help("the mode chain the estimator assumes, s x s: entries >= 0, rows sum to 1 "
                "(+-1e-9)"),
      Key::boolean("use_y0").or_default(true).help(
          "correct with y[0] at period 0 (xhat0, P0 are the prior of period 0); false: they are "
          "xhat(0|0), P(0|0)"),
  };
  return keys;
}

namespace {

// The scenario must have modes, at most 6 actuators and sensors sampled every period.
void check_mode_scenario(const config::Table& t, const Model& model) {
  if (model.plant.modes.empty() && model.actuators.empty()) {
    t.fail_here(
        "expected a scenario with modes: [[actuator]] tables or a jump_linear plant, got neither");
  }
  if (model.actuators.size() > 6) {
    t.fail_here(fmt::format("expected at most 6 actuators (64 modes) for a mode estimator, got {}",
                            model.actuators.size()));
  }
  for (const auto& s : model.sensors) {
    if (s.spec.every != 1 || s.spec.buffer != 0) {
      t.fail_here(fmt::format("expected sensors with every = 1 and buffer = 0 (sensor \"{}\")",
                              s.spec.name));
    }
  }
}

// `transition` (default: the model's chain), the stationary law and the mode prior mu0.
void read_mode_chain(const config::KeyReader& r, ModeSetup& setup) {
  ModeModel& mm = setup.model;
  const auto s = static_cast<Eigen::Index>(mm.modes());
  if (r.has("transition")) {
    Eigen::MatrixXd T = r.matrix("transition");
    config::require_shape(r.table(), "transition", T, s, s);
    for (Eigen::Index i = 0; i < s; ++i) {
      if (T.row(i).minCoeff() < 0.0 || std::abs(T.row(i).sum() - 1.0) > 1e-9) {
        r.fail("transition",
               fmt::format("expected non-negative rows summing to 1, row {} sums to {}", i,
                           T.row(i).sum()));
      }
    }
    mm.transition = std::move(T);
  }
  mm.stationary = models::stationary_law(mm.transition);
  setup.mu0 = r.string("mode_prior") == "uniform"
                  ? Eigen::VectorXd::Constant(s, 1.0 / static_cast<double>(s))
                  : mm.stationary;
}

// Initial estimate: the plant part from xhat0 (default x0), the held inputs from the
// actuators' u0 (known); or the whole augmented vector.
void read_mode_initial(const config::KeyReader& r, const Model& model, ModeSetup& setup) {
  const ModeModel& mm = setup.model;
  const Eigen::Index n = mm.n, na = mm.na;
  setup.x0 = Eigen::VectorXd::Zero(na);
  setup.x0.head(n) = model.plant.x0;
  for (std::size_t c = 0; c < mm.hold.size(); ++c) {
    setup.x0(n + static_cast<Eigen::Index>(c)) =
        model.actuators[static_cast<std::size_t>(mm.hold[c])].spec.u0;
  }
  setup.P0 = Eigen::MatrixXd::Zero(na, na);
  // Sizes accepted: n (the plant state), n + hold channels (the estimator's state), or
  // n + r (one entry per actuator; entries of "zero" channels are ignored).
  const auto ch = static_cast<Eigen::Index>(mm.channels);
  std::vector<Eigen::Index> pick;  // index into the given vector for each entry of z
  auto pick_for = [&](Eigen::Index size) {
    pick.clear();
    for (Eigen::Index i = 0; i < n; ++i) pick.push_back(i);
    if (size == na) {
      for (Eigen::Index c = 0; c < na - n; ++c) pick.push_back(n + c);
    } else if (size == n + ch) {
      for (const int c : mm.hold) pick.push_back(n + c);
    } else if (size != n) {
      return false;
    }
    return true;
  };
  const std::string sizes =
      ch > 0 ? fmt::format("{} (the state), {} (and the held inputs) or {} (and one per actuator)",
                           n, na, n + ch)
             : fmt::format("{} (the state)", n);
  if (r.has("xhat0")) {
    const Eigen::VectorXd v = r.vector("xhat0");
    if (!pick_for(v.size()))
      r.fail("xhat0", fmt::format("expected {} entries, got {}", sizes, v.size()));
    for (std::size_t a = 0; a < pick.size(); ++a)
      setup.x0(static_cast<Eigen::Index>(a)) = v(pick[a]);
  }
  if (r.has("P0")) {
    const Eigen::MatrixXd P = r.matrix("P0");
    if (P.rows() != P.cols() || !pick_for(P.rows())) {
      r.fail("P0", fmt::format("expected a square matrix of size {}, got {}x{}", sizes, P.rows(),
                               P.cols()));
    }
    for (std::size_t a = 0; a < pick.size(); ++a) {
      for (std::size_t b = 0; b < pick.size(); ++b) {
        setup.P0(static_cast<Eigen::Index>(a), static_cast<Eigen::Index>(b)) = P(pick[a], pick[b]);
      }
    }
    config::require_psd(r.table(), "P0", setup.P0);
  }
}

}  // namespace

ModeSetup read_mode_setup(const config::KeyReader& r, const Model& model) {
  check_mode_scenario(r.table(), model);
  ModeSetup setup;
  setup.model = build(model);
  read_mode_chain(r, setup);
  read_mode_initial(r, model, setup);
  setup.use_y0 = r.boolean("use_y0");
  return setup;
}

CurrentMeasurement::CurrentMeasurement(const ExtendedModel& ext0)
    : ext_(&ext0), window_(ext0, /*deduplicate=*/true), mask_(Eigen::VectorXd::Zero(ext0.nmb)) {}

Eigen::Index CurrentMeasurement::take(std::int64_t k) {
  window_.advance(k);
  mask_.setZero();
  Eigen::Index rows = 0;
  for (std::uint64_t bits = window_.pattern(); bits != 0; bits &= bits - 1) {
    const auto& f = ext_->fict[static_cast<std::size_t>(std::countr_zero(bits))];
    mask_.segment(f.row, f.rows).setOnes();
    rows += f.rows;
  }
  window_.clear_pattern();
  return rows;
}

ModeKalman::ModeKalman(const ModeModel& mm, const Eigen::VectorXd& x0, const Eigen::MatrixXd& P0)
    : mm_(&mm),
      x_(x0),
      xp_(x0),
      P_(P0),
      Pp_(P0),
      ws_(mm.na, mm.m),
      rows_(static_cast<std::size_t>(mm.m)) {}

Eigen::Index ModeKalman::select(const Eigen::VectorXd& mask) {
  used_ = 0;
  for (Eigen::Index r = 0; r < mask.size(); ++r) {
    if (mask(r) != 0.0) rows_[static_cast<std::size_t>(used_++)] = r;
  }
  for (Eigen::Index a = 0; a < used_; ++a) {
    const Eigen::Index ra = rows_[static_cast<std::size_t>(a)];
    ws_.C.row(a) = mm_->C.row(ra);
    for (Eigen::Index b = 0; b < used_; ++b)
      ws_.R(a, b) = mm_->R(ra, rows_[static_cast<std::size_t>(b)]);
  }
  ws_.m = used_;
  return used_;
}

void ModeKalman::selected(const Eigen::VectorXd& y, Eigen::VectorXd& out) const {
  for (Eigen::Index a = 0; a < used_; ++a) out(a) = y(rows_[static_cast<std::size_t>(a)]);
}

void ModeKalman::load(const Eigen::VectorXd& y) {
  for (Eigen::Index a = 0; a < used_; ++a) ws_.y(a) = y(rows_[static_cast<std::size_t>(a)]);
}

double ModeKalman::predicted_loglik(int j, const Eigen::VectorXd& u, const Eigen::VectorXd& y) {
  const auto uj = static_cast<std::size_t>(j);
  xp_.noalias() = mm_->A[uj] * x_;
  xp_.noalias() += mm_->B[uj] * u;
  Pp_ = P_;
  kalman::predict_covariance(mm_->A[uj], mm_->Q[uj], Pp_, ws_);
  load(y);
  if (kalman::factor(xp_, Pp_, ws_) != kalman::Factor::kOk) {
    return -std::numeric_limits<double>::infinity();
  }
  return ws_.log_likelihood();
}

void ModeKalman::predict(int j, const Eigen::VectorXd& u) {
  const auto uj = static_cast<std::size_t>(j);
  xp_.noalias() = mm_->A[uj] * x_;
  xp_.noalias() += mm_->B[uj] * u;
  x_.swap(xp_);
  kalman::predict_covariance(mm_->A[uj], mm_->Q[uj], P_, ws_);
}

void ModeKalman::update(const Eigen::VectorXd& y) {
  if (used_ == 0) return;
  load(y);
  if (kalman::factor(x_, P_, ws_) != kalman::Factor::kOk) {
    failed_ = true;
    return;
  }
  kalman::apply(x_, P_, ws_);
  if (!x_.allFinite()) failed_ = true;
}

bool bayes_log(const Eigen::VectorXd& prior, const Eigen::VectorXd& loglik, Eigen::VectorXd& p) {
  double amax = -std::numeric_limits<double>::infinity();
  for (Eigen::Index j = 0; j < prior.size(); ++j) {
    if (prior(j) > 0.0 && std::isfinite(loglik(j)))
      amax = std::max(amax, std::log(prior(j)) + loglik(j));
  }
  if (!std::isfinite(amax)) {
    p = prior;
    return false;
  }
  double sum = 0.0;
  for (Eigen::Index j = 0; j < prior.size(); ++j) {
    p(j) = prior(j) > 0.0 && std::isfinite(loglik(j))
               ? std::exp(std::log(prior(j)) + loglik(j) - amax)
               : 0.0;
    sum += p(j);
  }
  p /= sum;
  return true;
}

double kalman_flops(double na, double nue, double m) {
  // predict: A x + B u (2na² + 2na nue), A P A' + Q (4na³ + na²);
  // update: C P (2m na²), S (2m² na + m²), Cholesky (m³/3), two triangular solves (2m² + 2m² na),
  // x += U'w (2m na), P -= U'U (2m na² + na²).
  return 2 * na * na + 2 * na * nue + 4 * na * na * na + na * na + 2 * m * na * na +
         2 * m * m * na + m * m + m * m * m / 3 + 2 * m * m + 2 * m * m * na + 2 * m * na +
         2 * m * na * na + na * na;
}

}  // namespace ncosim::est
