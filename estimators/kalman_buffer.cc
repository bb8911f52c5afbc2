// estimators/kalman_buffer.cc
// The optimal estimator of Schenato (2008), Theorem 1, with a finite buffer of N periods: a
// time-varying Kalman filter over the plant state whose last N steps are kept in a ring (per
// slot s: the known drive, the prior and posterior estimate and covariance, and the samples
// of period s received so far). A sample of period s arriving at period k with delay
// k - s < N is stored in its slot, and the update of period k re-runs the filter from the
// oldest slot that received something new, over the stored priors: what did not change is
// not recomputed. A sample with delay >= N is discarded, a repeated one ignored (both
// counted). It uses exactly the information of kalman_extended with max_delay = N - 1, so the
// two give the same estimate; its cost grows as N n^3 instead of (n N)^3.
#include <fmt/format.h>

#include <algorithm>
#include <limits>

#include "estimators/buffer_common.h"
#include "estimators/kalman_update.h"
#include "estimators/kinds.h"

namespace ncosim::est {

namespace {

constexpr std::int64_t kNone = std::numeric_limits<std::int64_t>::min();

// FLOPs of one step by the formula of kalman_extended (Dolz et al. section 2) with nb = n and
// nmb = m rows: the prediction terms (skipped at period 0) and the correction terms (m > 0).
struct StepFlops {
  double predict = 0.0;
  double n = 0.0;
  double correct(double m) const {
    if (m == 0) return 0.0;
    return 4 * n * n * m + 2 * n * m * m + 5 * m * m * m + 2 * n * m + m * m + m;
  }
};

struct BufferShape {
  int N = 1;
  Eigen::Index n = 0;
  std::vector<Eigen::Index> ny;  // per sensor
  Eigen::MatrixXd A, Q;
  std::vector<Eigen::MatrixXd> C, R;
  StepFlops flops;
};

class KalmanBuffer final : public Estimator {
 public:
  KalmanBuffer(const BufferShape& shape, const InitialEstimate& init) : sh_(shape), init_(init) {
    slots_.resize(static_cast<std::size_t>(sh_.N) + 1);  // N live slots and the one before
    const Eigen::Index n = sh_.n;
    Eigen::Index rows = 0;
    for (auto r : sh_.ny) rows += r;
    for (auto& s : slots_) {
      s.drive = Eigen::VectorXd::Zero(n);
      s.xprior = s.xpost = Eigen::VectorXd::Zero(n);
      s.Pprior = s.Ppost = Eigen::MatrixXd::Zero(n, n);
      s.seen.assign(sh_.ny.size(), 0);
      s.values.resize(rows);
      s.sensor.reserve(sh_.ny.size());
    }
    ws_.reserve(n, rows);
    cur_ = &slots_[0];
    cur_->xpost = init.xhat0;
    cur_->Ppost = init.P0;
  }

  int on_packet(const Packet& p, std::int64_t k) override {
    const auto s_index = static_cast<std::size_t>(p.sensor);
    const Eigen::Index ny = sh_.ny[s_index];
    int used = 0;
    for (int i = 0; i < p.count; ++i) {
      const std::int64_t s = p.stamps[static_cast<std::size_t>(i)];
      const std::int64_t d = k - s;
      if (d < 0) continue;
      if (d >= sh_.N) {
        ++counters_.late;
        continue;
      }
      Slot& sl = slot(s);
      const bool fresh = !sl.seen[s_index] || p.independent_copy;
      if (!fresh) {
        ++counters_.duplicates;
        continue;
      }
      sl.seen[s_index] = 1;
      if (sl.rows + ny > sl.values.size()) sl.values.conservativeResize(sl.rows + ny);
      sl.values.segment(sl.rows, ny) = p.values.segment(i * ny, ny);
      sl.sensor.push_back(p.sensor);
      sl.rows += ny;
      dirty_ = std::min(dirty_, s);
      ++used;
    }
    return used;
  }

  void on_period(std::int64_t k, const PeriodInput& in) override {
    Slot& now = slot(k);
    now.drive = in.drive;
    const std::int64_t from = std::min(dirty_, k);
    dirty_ = std::numeric_limits<std::int64_t>::max();
    double spent = 0.0;
    for (std::int64_t s = from; s <= k; ++s) {
      Slot& sl = slot(s);
      if (s == k || s > from) {  // the prior of `from` (< k) is stored and still valid
        if (s == 0) {
          sl.xprior = init_.xhat0;
          sl.Pprior = init_.P0;
        } else {
          const Slot& prev = slot(s - 1);
          sl.xprior = prev.xpost;
          kalman::predict_state(sh_.A, sl.xprior, ws_);
          sl.xprior += sl.drive;
          sl.Pprior = prev.Ppost;
          kalman::predict_covariance(sh_.A, sh_.Q, sl.Pprior, ws_);
          spent += sh_.flops.predict;
        }
      }
      correct(sl);
      spent += sh_.flops.correct(static_cast<double>(sl.rows));
    }
    cur_ = &now;
    counters_.flops += spent;
    counters_.flops_worst = std::max(counters_.flops_worst, spent);
    ++counters_.periods;
    if (!now.xpost.allFinite()) failed_ = true;
  }

  StateView state() const override { return StateView(cur_->xpost.data(), sh_.n); }
  const Eigen::MatrixXd* covariance() const override { return &cur_->Ppost; }
  std::string status() const override { return failed_ ? "numerical_failure" : "ok"; }
  const RunCounters* counters() const override { return &counters_; }

 private:
  struct Slot {
    std::int64_t stamp = kNone;
    Eigen::VectorXd drive, xprior, xpost;
    Eigen::MatrixXd Pprior, Ppost;
    std::vector<char> seen;   // per sensor: its sample of this period was used
    std::vector<int> sensor;  // the sensor of each stored sample, in arrival order
    Eigen::VectorXd values;   // their values, stacked
    Eigen::Index rows = 0;
  };

  // The slot of period s, reset when it is reused for a new period (only ever the newest).
  Slot& slot(std::int64_t s) {
    Slot& sl = slots_[static_cast<std::size_t>(s % (sh_.N + 1))];
    if (sl.stamp != s) {
      sl.stamp = s;
      std::fill(sl.seen.begin(), sl.seen.end(), 0);
      sl.sensor.clear();
      sl.rows = 0;
    }
    return sl;
  }

  void correct(Slot& sl) {
    sl.xpost = sl.xprior;
    sl.Ppost = sl.Pprior;
    if (sl.rows == 0) return;
    const Eigen::Index m = sl.rows;
    if (m > ws_.C.rows()) ws_.reserve(sh_.n, m);  // independent copies beyond one per sensor
    ws_.R.topLeftCorner(m, m).setZero();
    Eigen::Index r = 0;
    for (int s : sl.sensor) {
      const auto u = static_cast<std::size_t>(s);
      const Eigen::Index ny = sh_.ny[u];
      ws_.C.middleRows(r, ny) = sh_.C[u];
      ws_.R.block(r, r, ny, ny) = sh_.R[u];
      r += ny;
    }
    ws_.y.head(m) = sl.values.head(m);
    ws_.m = m;
    if (!kalman::update(sl.xpost, sl.Ppost, ws_)) failed_ = true;
  }

  const BufferShape& sh_;
  const InitialEstimate& init_;
  std::vector<Slot> slots_;
  Slot* cur_ = nullptr;
  std::int64_t dirty_ = std::numeric_limits<std::int64_t>::max();
  kalman::Workspace ws_;
  RunCounters counters_;
  bool failed_ = false;
};

class KalmanBufferDesign final : public EstimatorDesign {
 public:
  KalmanBufferDesign(const Model& model, int N, InitialEstimate init) : init_(std::move(init)) {
    sh_.N = N;
    sh_.n = model.plant.n();
    sh_.A = model.plant.A;
    sh_.Q = model.plant.Bw * model.plant.W * model.plant.Bw.transpose();
    for (const auto& s : model.sensors) {
      sh_.ny.push_back(s.spec.ny());
      sh_.C.push_back(s.spec.C);
      sh_.R.push_back(s.spec.R);
    }
    const double n = static_cast<double>(sh_.n), nw = static_cast<double>(model.plant.nw());
    const double nu = static_cast<double>(model.plant.nu());
    sh_.flops.n = n;
    sh_.flops.predict = 2 * n * n * n + n * n * nw + n * nw * nw + 2 * n * n + n * nu + 2 * n;
    double rows = 0.0;
    for (auto r : sh_.ny) rows += static_cast<double>(r);
    worst_ = N * (sh_.flops.predict + sh_.flops.correct(rows));
    report_.method = "none";
    report_.extra["buffer"] = N;
    const auto lambda = arrival_probabilities(model, N);
    nlohmann::json lb = nlohmann::json::array();
    for (const auto& l : lambda) lb.push_back(l.back());
    report_.extra["lambda_buffer"] = lb;  // per sensor: lambda_{N-1} = P[delay <= N-1]
    report_.extra["flops_per_period_worst"] = worst_;
    if (!model.sensors.empty()) report_critical_probability(buffer_plant(model), report_.extra);
  }
  std::unique_ptr<Estimator> instantiate() const override {
    return std::make_unique<KalmanBuffer>(sh_, init_);
  }
  const DesignReport& report() const override { return report_; }
  // The worst case: every one of the N slots re-run, each with every sensor's sample (the mean
  // over a run is the summary's flops_mean).
  std::optional<double> flops_per_period() const override { return worst_; }
  bool is_kalman_reference() const override { return true; }

 private:
  BufferShape sh_;
  InitialEstimate init_;
  DesignReport report_;
  double worst_ = 0.0;
};

std::unique_ptr<EstimatorDesign> read_kalman_buffer(const config::Table& t, const Model& model) {
  const int N = read_buffer(config::KeyReader(t, buffer_keys()));
  return std::make_unique<KalmanBufferDesign>(model, N, read_initial(t, model));
}

// The design only computes design.json's critical probability (buffer_common.h) and keeps the
// model: the generic estimate on the plant state plus that.
DesignCost kalman_buffer_cost(const config::Table& /*t*/, const toml::table& /*raw*/,
                              const Model& model, const std::string& driver) {
  DesignCost c = critical_probability_cost(model, buffer_plant_stable(model));
  const DesignCost base = generic_design_cost(model);
  if (c.flops > base.flops) c.driver = moment_driver(driver, static_cast<double>(model.plant.n()));
  c.flops += base.flops;
  c.bytes += base.bytes;
  return c;
}

}  // namespace

void register_kalman_buffer(EstimatorRegistry& registry) {
  registry.add("kalman_buffer",
               "optimal Kalman filter re-run over a buffer of N periods (Schenato 2008): buffer",
               buffer_keys(), read_kalman_buffer, kalman_buffer_cost);
}

}  // namespace ncosim::est
