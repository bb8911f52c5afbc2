// estimators/static_buffer.cc
// The constant-gain estimator with a buffer of N periods of Schenato (2008), eqs. (23)–(25),
// with the optimal gains of Theorem 3 (estimators/design/buffer_design.h, gain indexing of
// the gain indexing of scenarios/README.md). At period t the slot of period t-N+1 closes: its
// estimate is predicted from the closed slot before it and corrected with K_{N-1} if its sample
// arrived (delay <= N-1); then the open slots t-N+2 .. t are re-predicted from it, the slot of
// delay k corrected with K_k if its sample has arrived. Several sensors are corrected one after the
// other in scenario order, each with its own gain. The cost is N prediction-corrections of the
// plant state, without covariances.
#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

#include "estimators/buffer_common.h"
#include "estimators/kinds.h"

namespace ncosim::est {

namespace {

struct StaticShape {
  int N = 1;
  Eigen::Index n = 0;
  std::vector<Eigen::Index> ny;
  Eigen::MatrixXd A;
  std::vector<Eigen::MatrixXd> C;
  std::vector<std::vector<Eigen::MatrixXd>> K;  // K[k][i]
  bool heavy_tail = false;
};

class StaticBuffer final : public Estimator {
 public:
  StaticBuffer(const StaticShape& sh, const InitialEstimate& init)
      : sh_(sh), xhat0_(init.xhat0), base_(init.xhat0), xi_(init.xhat0), pred_(sh.n) {
    Eigen::Index ny_max = 0;
    for (auto r : sh.ny) ny_max = std::max(ny_max, r);
    resid_.resize(ny_max);
    const auto S = sh.ny.size();
    slots_.resize(static_cast<std::size_t>(sh.N));
    for (auto& s : slots_) {
      s.drive = Eigen::VectorXd::Zero(sh.n);
      s.arrived.assign(S, 0);
      for (auto r : sh.ny) s.y.push_back(Eigen::VectorXd::Zero(r));
    }
  }

  int on_packet(const Packet& p, std::int64_t k) override {
    const auto u = static_cast<std::size_t>(p.sensor);
    const Eigen::Index ny = sh_.ny[u];
    int used = 0;
    for (int i = 0; i < p.count; ++i) {
      const std::int64_t s = p.stamps[static_cast<std::size_t>(i)];
      const std::int64_t d = k - s;
      if (d < 0 || d >= sh_.N) continue;
      Slot& sl = slot(s);
      if (sl.arrived[u]) continue;  // a repeat or an extra copy: one sample per slot
      sl.arrived[u] = 1;
      sl.y[u] = p.values.segment(i * ny, ny);
      ++used;
    }
    return used;
  }

  void on_period(std::int64_t t, const PeriodInput& in) override {
    slot(t).drive = in.drive;
    const std::int64_t c = t - sh_.N + 1;  // the slot that closes now (delay N-1)
    if (c >= 0) step(base_, c, sh_.N - 1);
    xi_ = base_;
    for (std::int64_t s = std::max<std::int64_t>(c + 1, 0); s <= t; ++s)
      step(xi_, s, static_cast<int>(t - s));
    if (!xi_.allFinite()) failed_ = true;
  }

  StateView state() const override { return StateView(xi_.data(), sh_.n); }
  std::string status() const override {
    return failed_ ? "numerical_failure" : sh_.heavy_tail ? "heavy_tail" : "ok";
  }

 private:
  struct Slot {
    std::int64_t stamp = std::numeric_limits<std::int64_t>::min();
    Eigen::VectorXd drive;
    std::vector<char> arrived;
    std::vector<Eigen::VectorXd> y;
  };
  Slot& slot(std::int64_t s) {
    Slot& sl = slots_[static_cast<std::size_t>(s % sh_.N)];
    if (sl.stamp != s) {
      sl.stamp = s;
      std::fill(sl.arrived.begin(), sl.arrived.end(), 0);
    }
    return sl;
  }
  // x <- estimate of slot s from x (the estimate of slot s-1; x[0] is predicted by xhat0),
  // corrected with the gains of delay k.
  void step(Eigen::VectorXd& x, std::int64_t s, int k) {
    const Slot& sl = slot(s);
    if (s == 0) {
      x = xhat0_;
    } else {
      pred_.noalias() = sh_.A * x;
      x = pred_ + sl.drive;
    }
    for (std::size_t i = 0; i < sl.arrived.size(); ++i) {
      if (!sl.arrived[i]) continue;
      const auto& K = sh_.K[static_cast<std::size_t>(k)][i];
      auto r = resid_.head(sh_.ny[i]);  // y - C x without a temporary
      r = sl.y[i];
      r.noalias() -= sh_.C[i] * x;
      x.noalias() += K * r;
    }
  }

  const StaticShape& sh_;
  Eigen::VectorXd xhat0_, base_, xi_, pred_, resid_;
  std::vector<Slot> slots_;
  bool failed_ = false;
};

class StaticBufferDesign final : public EstimatorDesign {
 public:
  StaticBufferDesign(const Model& model, int N, InitialEstimate init) : init_(std::move(init)) {
    const auto t0 = std::chrono::steady_clock::now();
    const auto plant = buffer_plant(model);
    const auto lambda = arrival_probabilities(model, N);
    const auto g = buffer::design_static_gains(plant, lambda);
    report_.design_seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    sh_.N = N;
    sh_.n = model.plant.n();
    sh_.A = model.plant.A;
    sh_.C = plant.C;
    for (const auto& s : model.sensors) sh_.ny.push_back(s.spec.ny());
    sh_.K = g.K;
    sh_.heavy_tail = g.stable && !(g.fourth_moment_radius < 1.0);
    report_.method = "theorem3";
    long gains = 0;
    for (const auto& s : model.sensors) gains += static_cast<long>(s.spec.ny());
    report_.stored_gains = gains * N;
    report_.stable = g.stable;
    if (g.stable) {
      report_.predicted_mse = g.filtered.trace();
    } else {
      report_.status = g.status;
    }
    auto& x = report_.extra;
    x["buffer"] = N;
    x["lambda"] = lambda;  // per sensor: lambda_0 .. lambda_{N-1}
    x["trace_V0"] = g.stable ? nlohmann::json(g.trace_V0) : nlohmann::json(nullptr);
    x["second_moment_radius"] = g.second_moment_radius;
    x["fourth_moment_radius"] = std::isfinite(g.fourth_moment_radius)
                                    ? nlohmann::json(g.fourth_moment_radius)
                                    : nlohmann::json(nullptr);
    x["heavy_tail"] = sh_.heavy_tail;
    nlohmann::json K = nlohmann::json::array();  // K[k][i] = the gain of delay k, sensor i (n x ny)
    for (const auto& gk : g.K) {
      nlohmann::json per = nlohmann::json::array();
      for (const auto& m : gk) {
        nlohmann::json rows = nlohmann::json::array();
        for (Eigen::Index r = 0; r < m.rows(); ++r) {
          nlohmann::json row = nlohmann::json::array();
          for (Eigen::Index c = 0; c < m.cols(); ++c)
            row.push_back(std::isfinite(m(r, c)) ? m(r, c) : 0.0);
          rows.push_back(row);
        }
        per.push_back(rows);
      }
      K.push_back(per);
    }
    x["gains"] = K;
    report_critical_probability(plant, x);
    double rows = 0.0;
    for (auto r : sh_.ny) rows += static_cast<double>(r);
    const double n = static_cast<double>(sh_.n), nu = static_cast<double>(model.plant.nu());
    // Per slot: A x (2n^2) + drive (n) + per row 2n (C x) + 1 + 2n (K r) + n... ~ 2n^2 + n + 4 n
    // rows.
    flops_ = N * (2 * n * n + n + n * nu + 4 * n * rows + rows);
  }
  std::unique_ptr<Estimator> instantiate() const override {
    return std::make_unique<StaticBuffer>(sh_, init_);
  }
  const DesignReport& report() const override { return report_; }
  std::optional<double> flops_per_period() const override { return flops_; }

 private:
  StaticShape sh_;
  InitialEstimate init_;
  DesignReport report_;
  double flops_ = 0.0;
};

std::unique_ptr<EstimatorDesign> read_static_buffer(const config::Table& t, const Model& model) {
  const int N = read_buffer(config::KeyReader(t, buffer_keys()));
  if (model.sensors.empty()) t.fail("kind", "static_buffer needs at least one [[sensor]]");
  for (const auto& s : model.sensors) {
    if (s.spec.every != 1) {
      t.fail("kind",
             fmt::format(
                 "static_buffer needs sensors sampled every period; sensor '{}' has every = {}",
                 s.spec.name, s.spec.every));
    }
  }
  return std::make_unique<StaticBufferDesign>(model, N, read_initial(t, model));
}

// Theorem 3's gains: the Riccati fixed point of the oldest slot (kBufferMomentSolves moment
// solves, buffer_common.h) and its second-moment radius, the N slots' gains and covariances (about
// 10 n^3 per slot and sensor, all kept), the critical probability, and for n <= 7 the
// fourth-moment radius: E[F^{x4}] is an n^4 x n^4 matrix, one dense product per sensor, then an
// eigenvalue solve: 64 products' work in all (measured by tests/costs: 0.096 s of CPU for n = 4
// and one sensor at 12 GFLOP/s, 69 products of 256 x 256). Five states and 1001 sensors: about
// 7 minutes.
DesignCost static_buffer_cost(const config::Table& /*t*/, const toml::table& raw,
                              const Model& model, const std::string& driver) {
  const double n = static_cast<double>(model.plant.n());
  const double ny = static_cast<double>(model.total_outputs());
  const double sensors = static_cast<double>(model.sensors.size());
  const double N = peek_buffer(raw);
  DesignCost c = critical_probability_cost(model, buffer_plant_stable(model));
  const DesignCost base = generic_design_cost(model);
  const double m = n * n;
  c.flops += (kBufferMomentSolves + 1.0) * moment_solve_flops(n, sensors) +
             N * std::max(sensors, 1.0) * 10.0 * n * n * n + base.flops;
  c.bytes = std::max(c.bytes, 8.0 * 8.0 * m * m) + 8.0 * (N + 1.0) * (n * n + n * ny) + base.bytes;
  c.driver = moment_driver(driver, n);
  if (n <= 7.0) {
    const double big = m * m;
    c.bytes += 8.0 * 4.0 * big * big;
    c.flops += (2.0 * sensors + 64.0) * big * big * big;
    c.driver = fmt::format(
        "{} and the {} sensor(s) (the fourth-moment operator is {:.0f} x {:.0f}, one product per "
        "sensor)",
        driver, sensors, big, big);
  }
  return c;
}

}  // namespace

void register_static_buffer(EstimatorRegistry& registry) {
  registry.add(
      "static_buffer",
      "constant optimal gains over a buffer of N periods (Schenato 2008, Theorem 3): buffer",
      buffer_keys(), read_static_buffer, static_buffer_cost);
}

}  // namespace ncosim::est
