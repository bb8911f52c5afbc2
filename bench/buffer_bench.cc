// bench/buffer_bench.cc — Schenato (2008) on the pendulum: per-period cost of kalman_buffer
// against the buffer length N, against kalman_extended with max_delay = N - 1 (the same
// information) and static_buffer; the Theorem 3 design time; lambda_c by bisection and by SDP.
#include <benchmark/benchmark.h>

#include <memory>
#include <vector>

#include "estimators/design/buffer_design.h"
#include "sim/scenario/registries.h"
#include "sim/scenario/scenario.h"

namespace ncosim {
namespace {

const std::string kPendulum =
    std::string(NCOSIM_SOURCE_DIR) + "/scenarios/schenato2008_pendulum.toml";
constexpr int kPeriods = 4096;

// Packets of 4096 periods from the paper's link (lambda_h = 0.05 h, 0.75 beyond), replayed
// period by period; the estimator is instantiated fresh for each pass.
struct Stream {
  std::unique_ptr<sim::Scenario> sc;
  std::vector<std::vector<est::Packet>> per_period;
};

Stream& stream() {
  static Stream s = [] {
    Stream st;
    st.sc = std::move(sim::load_cases(kPendulum, {}).cases.front().scenario);
    st.per_period.resize(kPeriods);
    kernel::Rng rng = kernel::make_stream(1, 0, 0);
    auto link = st.sc->model.sensors[0].link->clone();
    for (int k = 0; k < kPeriods; ++k) {
      const auto d = link->transmit(rng);
      if (d == models::kLost || k + d >= kPeriods) continue;
      est::Packet p;
      p.sensor = 0;
      p.send_period = k;
      p.count = 1;
      p.stamps = {k};
      p.values = Eigen::VectorXd::Constant(1, 0.1 * (k % 7));
      st.per_period[static_cast<std::size_t>(k + d)].push_back(p);
    }
    return st;
  }();
  return s;
}

std::unique_ptr<est::EstimatorDesign> design(const std::string& kind, const std::string& key,
                                             int value) {
  const auto& model = stream().sc->model;
  toml::table t{{key, value}};
  return sim::estimator_registry().find(kind)->factory(config::Table(t, "estimator[0]", "bench"),
                                                       model);
}

void replay(benchmark::State& state, const est::EstimatorDesign& d) {
  Stream& s = stream();
  const Eigen::VectorXd u = Eigen::VectorXd::Zero(0), drive = Eigen::VectorXd::Constant(2, 0.01);
  const est::PeriodInput in{u, drive};
  double flops = 0.0, worst = 0.0;
  for (auto _ : state) {
    auto e = d.instantiate();
    for (int k = 0; k < kPeriods; ++k) {
      for (const auto& p : s.per_period[static_cast<std::size_t>(k)]) e->on_packet(p, k);
      e->on_period(k, in);
    }
    benchmark::DoNotOptimize(e->state().data());
    if (const auto* c = e->counters()) {
      flops = c->flops / static_cast<double>(c->periods);
      worst = c->flops_worst;
    }
  }
  state.SetItemsProcessed(state.iterations() * kPeriods);
  if (flops > 0) {
    state.counters["flops_mean"] = flops;
    state.counters["flops_worst"] = worst;
  }
  if (const auto f = d.flops_per_period()) state.counters["flops_bound"] = *f;
}

void BM_KalmanBuffer(benchmark::State& state) {
  replay(state, *design("kalman_buffer", "buffer", static_cast<int>(state.range(0))));
}
void BM_KalmanExtended(benchmark::State& state) {
  replay(state, *design("kalman_extended", "max_delay", static_cast<int>(state.range(0)) - 1));
}
void BM_StaticBuffer(benchmark::State& state) {
  replay(state, *design("static_buffer", "buffer", static_cast<int>(state.range(0))));
}
BENCHMARK(BM_KalmanBuffer)->DenseRange(1, 16, 1);
BENCHMARK(BM_KalmanExtended)->DenseRange(1, 16, 1);
BENCHMARK(BM_StaticBuffer)->Arg(1)->Arg(4)->Arg(8)->Arg(16);

est::buffer::Plant pendulum() {
  est::buffer::Plant p;
  p.A = (Eigen::MatrixXd(2, 2) << 1.2, 0.1, 0.0, 0.8).finished();
  p.Q = (Eigen::MatrixXd(2, 2) << 0.2, 0.1, 0.1, 1.0).finished();
  p.C = {(Eigen::MatrixXd(1, 2) << 1.0, 0.0).finished()};
  p.R = {Eigen::MatrixXd::Identity(1, 1)};
  return p;
}

void BM_StaticGainsDesign(benchmark::State& state) {
  const auto p = pendulum();
  std::vector<double> lambda;
  for (int h = 0; h < state.range(0); ++h) lambda.push_back(0.05 * h);
  for (auto _ : state)
    benchmark::DoNotOptimize(est::buffer::design_static_gains(p, {lambda}).trace_V0);
}
BENCHMARK(BM_StaticGainsDesign)->Arg(8)->Arg(16)->Unit(benchmark::kMicrosecond);

void BM_CriticalProbabilityBisection(benchmark::State& state) {
  const auto p = pendulum();
  for (auto _ : state)
    benchmark::DoNotOptimize(est::buffer::critical_probability_bisection(p).value);
}
void BM_CriticalProbabilitySdp(benchmark::State& state) {
  const auto p = pendulum();
  for (auto _ : state) benchmark::DoNotOptimize(est::buffer::critical_probability_sdp(p).value);
}
BENCHMARK(BM_CriticalProbabilityBisection)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_CriticalProbabilitySdp)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace ncosim
