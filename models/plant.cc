// models/plant.cc — lti and lti_continuous plant readers; exact discretisation.
#include "models/plant.h"

#include <fmt/format.h>

#include <unsupported/Eigen/MatrixFunctions>

#include "config/keys.h"
#include "models/plant_process.h"

namespace ncosim::models {

double LinearPlant::spectral_radius() const {
  if (A.size() == 0) return 0.0;
  return A.eigenvalues().cwiseAbs().maxCoeff();
}

Eigen::MatrixXd psd_sqrt(const Eigen::MatrixXd& M) {
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(0.5 * (M + M.transpose()));
  const Eigen::VectorXd d = es.eigenvalues().cwiseMax(0.0).cwiseSqrt();
  return es.eigenvectors() * d.asDiagonal() * es.eigenvectors().transpose();
}

LinearPlant discretise(const Eigen::MatrixXd& Ac, const Eigen::MatrixXd& Bc,
                       const Eigen::MatrixXd& Gc, const Eigen::MatrixXd& Wc, double period) {
  const Eigen::Index n = Ac.rows();
  const Eigen::Index nu = Bc.cols();
  LinearPlant p;
  // ZOH: expm([[Ac, Bc], [0, 0]] T) = [[A, Bu], [0, I]].
  Eigen::MatrixXd M = Eigen::MatrixXd::Zero(n + nu, n + nu);
  M.topLeftCorner(n, n) = Ac * period;
  if (nu > 0) M.topRightCorner(n, nu) = Bc * period;
  const Eigen::MatrixXd E = M.exp();
  p.A = E.topLeftCorner(n, n);
  p.Bu = E.topRightCorner(n, nu);
  // Van Loan: expm([[-Ac, Q], [0, Ac']] T) = [[., G12], [0, G22]], W = G22' G12.
  const Eigen::MatrixXd Qc = Gc * Wc * Gc.transpose();
  Eigen::MatrixXd V = Eigen::MatrixXd::Zero(2 * n, 2 * n);
  V.topLeftCorner(n, n) = -Ac * period;
  V.topRightCorner(n, n) = Qc * period;
  V.bottomRightCorner(n, n) = Ac.transpose() * period;
  const Eigen::MatrixXd G = V.exp();
  const Eigen::MatrixXd W = G.bottomRightCorner(n, n).transpose() * G.topRightCorner(n, n);
  p.W = 0.5 * (W + W.transpose());
  p.Bw = Eigen::MatrixXd::Identity(n, n);
  p.x0 = Eigen::VectorXd::Zero(n);
  return p;
}

void Disturbance::at(std::int64_t k, Eigen::VectorXd& out) const {
  if (empty()) return;
  out += offset;
  const double kk = static_cast<double>(k);
  for (const auto& s : sines) out += s.amplitude * std::sin(s.omega * kk + s.phase);
}

Disturbance read_disturbance(const config::Table& plant_table, Eigen::Index nw) {
  Disturbance d;
  const auto t = plant_table.opt_table("disturbance");
  if (!t) return d;
  auto read_channels = [&](const config::Table& tt, std::string_view key) {
    Eigen::VectorXd v = tt.vector(key);
    if (v.size() == 1 && nw > 1) v = Eigen::VectorXd::Constant(nw, v(0));
    if (v.size() != nw) {
      tt.fail(key, fmt::format("expected 1 or {} entries (the disturbance size nw), got {}", nw,
                               v.size()));
    }
    if (!v.allFinite()) tt.fail(key, "expected finite values");
    return v;
  };
  d.offset = t->has("offset") ? read_channels(*t, "offset") : Eigen::VectorXd::Zero(nw);
  for (const config::Table& st : t->tables("sine")) {
    Disturbance::Sine s;
    s.amplitude = read_channels(st, "amplitude");
    s.omega = st.number("omega");
    s.phase = st.number_or("phase", 0.0);
    if (!std::isfinite(s.omega) || !std::isfinite(s.phase))
      st.fail_here("expected a finite omega and phase");
    st.finish();
    d.sines.push_back(std::move(s));
  }
  t->finish();
  return d;
}

LinearPlant discretise_transfer_function(const std::vector<double>& num,
                                         const std::vector<double>& den, double dead_time,
                                         double period) {
  const auto m = static_cast<Eigen::Index>(den.size()) - 1;
  // Controllable canonical form of num/den (den monic after scaling).
  Eigen::MatrixXd Ac = Eigen::MatrixXd::Zero(m, m);
  const double a0 = den[0];
  for (Eigen::Index i = 0; i + 1 < m; ++i) Ac(i, i + 1) = 1.0;
  for (Eigen::Index j = 0; j < m; ++j) Ac(m - 1, j) = -den[static_cast<std::size_t>(m - j)] / a0;
  Eigen::VectorXd Bc = Eigen::VectorXd::Zero(m);
  Bc(m - 1) = 1.0;
  Eigen::RowVectorXd Cc = Eigen::RowVectorXd::Zero(m);
  const auto nn = static_cast<Eigen::Index>(num.size());
  for (Eigen::Index j = 0; j < nn; ++j) Cc(j) = num[static_cast<std::size_t>(nn - 1 - j)] / a0;
  // Scaling (x~_j = x_j omega^j / k, omega the geometric mean of the pole magnitudes): the
  // canonical states are successive derivatives and differ by powers of omega; scaled, the
  // largest output coefficient is 1 and the model is well conditioned for the LMI designs.
  const double omega = std::pow(std::abs(den.back() / a0), 1.0 / static_cast<double>(m));
  if (std::isfinite(omega) && omega > 0.0) {
    Eigen::VectorXd s(m);
    for (Eigen::Index j = 0; j < m; ++j) s(j) = std::pow(omega, -static_cast<double>(j));
    const double k = (Cc.transpose().array() / s.array()).abs().maxCoeff();
    if (k > 0.0 && std::isfinite(k)) {
      s *= k;  // x~ = S x, S = diag(s)
      Ac = s.asDiagonal() * Ac * s.cwiseInverse().asDiagonal();
      Bc = s.asDiagonal() * Bc;
      Cc = Cc * s.cwiseInverse().asDiagonal();
    }
  }
  // int_0^s e^{Ac r} dr Bc and e^{Ac s} from one block exponential.
  auto zoh = [&](double s, Eigen::MatrixXd& Phi, Eigen::VectorXd& Gamma) {
    Eigen::MatrixXd M = Eigen::MatrixXd::Zero(m + 1, m + 1);
    M.topLeftCorner(m, m) = Ac * s;
    M.topRightCorner(m, 1) = Bc * s;
    const Eigen::MatrixXd E = M.exp();
    Phi = E.topLeftCorner(m, m);
    Gamma = E.topRightCorner(m, 1);
  };
  Eigen::MatrixXd A, Phi_a, Phi_b;
  Eigen::VectorXd Gamma, G_a, G_b;
  zoh(period, A, Gamma);
  // dead_time = d T + f, 0 <= f < T: x[k+1] = A x[k] + G0 u[k-d] + G1 u[k-d-1].
  auto d = static_cast<Eigen::Index>(std::floor(dead_time / period + 1e-9));
  double f = dead_time - static_cast<double>(d) * period;
  if (f < 1e-9 * period) f = 0.0;
  zoh(period - f, Phi_a, G_a);  // G0 = int_0^{T-f} e^{As} ds B
  zoh(f, Phi_b, G_b);
  const Eigen::VectorXd G0 = G_a;
  const Eigen::VectorXd G1 = Phi_a * G_b;      // e^{A(T-f)} int_0^f e^{As} ds B
  const Eigen::Index D = f > 0.0 ? d + 1 : d;  // held past inputs u[k-1] .. u[k-D]
  const Eigen::Index n = m + D;
  LinearPlant p;
  p.A = Eigen::MatrixXd::Zero(n, n);
  p.Bu = Eigen::MatrixXd::Zero(n, 1);
  p.A.topLeftCorner(m, m) = A;
  auto input_column = [&](Eigen::Index lag, const Eigen::VectorXd& g) {  // coefficient of u[k-lag]
    if (lag == 0) {
      p.Bu.topRows(m) += g;
    } else {
      p.A.block(0, m + lag - 1, m, 1) += g;
    }
  };
  input_column(d, G0);
  if (f > 0.0) input_column(d + 1, G1);
  if (D > 0) {
    p.Bu(m) = 1.0;  // u[k-1] <- u[k]
    for (Eigen::Index j = 1; j < D; ++j) p.A(m + j, m + j - 1) = 1.0;
  }
  p.Bw = Eigen::MatrixXd::Zero(n, 1);
  p.Bw.topRows(m) = Gamma;
  p.W = Eigen::MatrixXd::Zero(1, 1);
  p.x0 = Eigen::VectorXd::Zero(n);
  p.C_out = Eigen::MatrixXd::Zero(1, n);
  p.C_out.leftCols(m) = Cc;
  return p;
}

namespace {

using config::Key;

Key x0_key() { return Key::vector("x0").optional("zeros").help("initial state (n entries)"); }

const config::Keys& lti_keys() {
  static const config::Keys keys{
      Key::matrix("A").help("state matrix, n x n (square); n = its size"),
      Key::matrix("Bu").optional("no input (nu = 0)").help("input matrix, n x nu"),
      Key::matrix("Bw").optional("identity n x n").help("noise input matrix, n x nw"),
      Key::matrix("W").help(
          "process-noise covariance, nw x nw (nw = columns of Bw), symmetric positive "
          "semidefinite"),
      x0_key(),
  };
  return keys;
}

const config::Keys& lti_continuous_keys() {
  static const config::Keys keys{
      Key::matrix("Ac").unit("1/s").help("continuous state matrix, n x n (square)"),
      Key::matrix("Bc").optional("no input").help("continuous input matrix, n x nu"),
      Key::matrix("Gc").optional("identity n x n").help("noise input matrix, n x q"),
      Key::matrix("Wc").help(
          "noise intensity (per second), q x q (q = columns of Gc), symmetric positive "
          "semidefinite"),
      x0_key(),
  };
  return keys;
}

const config::Keys& mode_keys() {
  static const config::Keys keys{
      Key::matrix("A").optional("the base A").help("this mode's A, n x n"),
      Key::matrix("Bu").optional("the base Bu").help("this mode's Bu, n x nu"),
      Key::matrix("Bw").optional("the base Bw").help("this mode's Bw, n x nw"),
      Key::matrix("W").optional("the base W").help("this mode's W, covariance nw x nw"),
  };
  return keys;
}

const config::Keys& jump_linear_keys() {
  static const config::Keys keys =
      lti_keys() +
      config::Keys{
          Key::tables("mode")
              .fields(mode_keys())
              .help("[[plant.mode]]: 2 .. 64 tables; mode j = the j-th table (0-based), each "
                    "overriding any of the base A, Bu, Bw, W"),
          Key::matrix("transition").help("mode chain, s x s: entries >= 0, rows sum to 1 (+-1e-9)"),
          Key::vector("initial_mode")
              .optional("the stationary law of transition")
              .help("law of theta[0]: s entries >= 0 summing to 1"),
      };
  return keys;
}

const config::Keys& transfer_function_keys() {
  static const config::Keys keys{
      Key::numbers("num").help(
          "numerator, descending powers of s: 1 .. deg(den) finite coefficients"),
      Key::numbers("den").help(
          "denominator, descending powers of s: degree >= 1, leading coefficient non-zero"),
      Key::number("dead_time").or_default(0.0).unit("s").help("input dead time, 0 .. 1000 periods"),
      Key::number("W")
          .or_default(0.0)
          .min(0.0)
          .noun("a variance")
          .help("variance of the input disturbance (per period)"),
  };
  return keys;
}

Eigen::MatrixXd read_square(const config::KeyReader& t, std::string_view key) {
  Eigen::MatrixXd A = t.matrix(key);
  if (A.rows() != A.cols()) {
    t.fail(key, fmt::format("expected a square matrix, got {}x{}", A.rows(), A.cols()));
  }
  return A;
}

Eigen::VectorXd read_x0(const config::KeyReader& t, Eigen::Index n) {
  if (!t.has("x0")) return Eigen::VectorXd::Zero(n);
  Eigen::VectorXd x0 = t.vector("x0");
  if (x0.size() != n)
    t.fail("x0", fmt::format("expected {} entries (the state size), got {}", n, x0.size()));
  return x0;
}

LinearPlant read_lti_keys(const config::KeyReader& t) {
  const config::Table& table = t.table();
  LinearPlant p;
  p.A = read_square(t, "A");
  const Eigen::Index n = p.A.rows();
  p.Bu = t.has("Bu") ? t.matrix("Bu") : Eigen::MatrixXd::Zero(n, 0);
  if (p.Bu.rows() != n) config::require_shape(table, "Bu", p.Bu, n, p.Bu.cols());
  p.Bw = t.has("Bw") ? t.matrix("Bw") : Eigen::MatrixXd::Identity(n, n);
  if (p.Bw.rows() != n) config::require_shape(table, "Bw", p.Bw, n, p.Bw.cols());
  p.W = t.matrix("W");
  config::require_shape(table, "W", p.W, p.Bw.cols(), p.Bw.cols());
  config::require_psd(table, "W", p.W);
  p.x0 = read_x0(t, n);
  return p;
}

LinearPlant read_lti(const config::Table& t, double /*period*/) {
  return read_lti_keys(config::KeyReader(t, lti_keys()));
}

LinearPlant read_lti_continuous(const config::Table& table, double period) {
  const config::KeyReader t(table, lti_continuous_keys());
  const Eigen::MatrixXd Ac = read_square(t, "Ac");
  const Eigen::Index n = Ac.rows();
  Eigen::MatrixXd Bc = t.has("Bc") ? t.matrix("Bc") : Eigen::MatrixXd::Zero(n, 0);
  if (Bc.rows() != n) config::require_shape(table, "Bc", Bc, n, Bc.cols());
  Eigen::MatrixXd Gc = t.has("Gc") ? t.matrix("Gc") : Eigen::MatrixXd::Identity(n, n);
  if (Gc.rows() != n) config::require_shape(table, "Gc", Gc, n, Gc.cols());
  Eigen::MatrixXd Wc = t.matrix("Wc");
  config::require_shape(table, "Wc", Wc, Gc.cols(), Gc.cols());
  config::require_psd(table, "Wc", Wc);
  LinearPlant p = discretise(Ac, Bc, Gc, Wc, period);
  p.x0 = read_x0(t, n);
  return p;
}

// jump_linear: the lti keys are the base; each [[plant.mode]] overrides A, Bu, Bw, W.
LinearPlant read_jump_linear(const config::Table& table, double /*period*/) {
  const config::KeyReader t(table, jump_linear_keys());
  LinearPlant p = read_lti_keys(t);
  const Eigen::Index n = p.n();
  const auto tables = t.tables("mode");
  if (tables.size() < 2 || tables.size() > 64) {
    t.fail("mode", fmt::format("expected 2..64 [[plant.mode]] tables, got {}", tables.size()));
  }
  for (const config::Table& mt : tables) {
    const config::KeyReader mr(mt, mode_keys());
    const config::Table& m = mt;
    PlantMode pm{p.A, p.Bu, p.Bw, p.W};
    if (mr.has("A")) {
      pm.A = mr.matrix("A");
      config::require_shape(m, "A", pm.A, n, n);
    }
    if (mr.has("Bu")) {
      pm.Bu = mr.matrix("Bu");
      config::require_shape(m, "Bu", pm.Bu, n, p.nu());
    }
    if (mr.has("Bw")) {
      pm.Bw = mr.matrix("Bw");
      config::require_shape(m, "Bw", pm.Bw, n, p.nw());
    }
    if (mr.has("W")) {
      pm.W = mr.matrix("W");
      config::require_shape(m, "W", pm.W, p.nw(), p.nw());
      config::require_psd(m, "W", pm.W);
    }
    m.finish();
    p.modes.push_back(std::move(pm));
  }
  const auto s = static_cast<Eigen::Index>(p.modes.size());
  p.mode_transition = t.matrix("transition");
  config::require_shape(table, "transition", p.mode_transition, s, s);
  for (Eigen::Index i = 0; i < s; ++i) {
    const auto row = p.mode_transition.row(i);
    if (row.minCoeff() < 0.0 || std::abs(row.sum() - 1.0) > 1e-9) {
      t.fail("transition", fmt::format("expected non-negative rows summing to 1, row {} sums to {}",
                                       i, row.sum()));
    }
  }
  if (t.has("initial_mode")) {
    p.mode_initial = t.vector("initial_mode");
    if (p.mode_initial.size() != s || p.mode_initial.minCoeff() < 0.0 ||
        std::abs(p.mode_initial.sum() - 1.0) > 1e-9) {
      t.fail("initial_mode",
             fmt::format("expected {} non-negative entries summing to 1, got [{}]", s,
                         fmt::join(p.mode_initial.data(),
                                   p.mode_initial.data() + p.mode_initial.size(), ", ")));
    }
  } else {
    p.mode_initial = stationary_law(p.mode_transition);
  }
  p.process = jump_linear_process;
  return p;
}

LinearPlant read_transfer_function(const config::Table& table, double period) {
  const config::KeyReader t(table, transfer_function_keys());
  const std::vector<double> num = t.numbers("num");
  const std::vector<double> den = t.numbers("den");
  if (den.size() < 2 || den[0] == 0.0) {
    t.fail(
        "den",
        "expected the denominator's coefficients in descending powers of s, of degree >= 1 with a "
        "non-zero leading coefficient");
  }
  if (num.empty() || num.size() >= den.size()) {
    t.fail(
        "num",
        fmt::format(
            "expected a strictly proper transfer function (1..{} numerator coefficients), got {}",
            den.size() - 1, num.size()));
  }
  for (double v : num)
    if (!std::isfinite(v)) t.fail("num", "expected finite coefficients");
  for (double v : den)
    if (!std::isfinite(v)) t.fail("den", "expected finite coefficients");
  const double dead_time = t.number("dead_time");
  if (!(dead_time >= 0.0) || dead_time > 1000.0 * period) {
    t.fail("dead_time",
           fmt::format("expected a dead time in [0, 1000 periods] seconds, got {}", dead_time));
  }
  LinearPlant p = discretise_transfer_function(num, den, dead_time, period);
  // The input disturbance: variance of the held disturbance on the input channel.
  p.W = Eigen::MatrixXd::Constant(1, 1, t.number("W"));
  return p;
}

}  // namespace

void register_plants(PlantRegistry& registry) {
  registry.add("lti", "discrete LTI plant: A, Bu (optional), Bw (default I), W, x0", lti_keys(),
               read_lti);
  registry.add("lti_continuous",
               "continuous LTI plant discretised at the period: Ac, Bc, Gc (default I), Wc "
               "(noise intensity), x0 (ZOH, Van Loan)",
               lti_continuous_keys(), read_lti_continuous);
  registry.add(
      "jump_linear",
      "Markov jump linear plant: the lti keys as base, [[plant.mode]] tables overriding A, Bu, "
      "Bw, W, transition (mode chain), initial_mode (default: stationary)",
      jump_linear_keys(), read_jump_linear);
  registry.add(
      "transfer_function",
      "continuous SISO transfer function with dead time, ZOH at the period: num, den (descending "
      "powers of s), dead_time (s), W (variance of the input disturbance); sensors use C = "
      "\"output\"",
      transfer_function_keys(), read_transfer_function);
}

}  // namespace ncosim::models
