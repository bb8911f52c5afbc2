// bench/estimators_bench.cc — per-period update of each estimator (system A3 of Dolz et al.
// 2014, Table 2 configuration), the S4 design, and the whole flagship scenario.
#include <benchmark/benchmark.h>

#include <cmath>
#include <memory>
#include <vector>

#include "estimators/design/jump_design.h"
#include "estimators/extended_model.h"
#include "sim/run/campaign.h"
#include "sim/scenario/registries.h"
#include "sim/scenario/scenario.h"

namespace ncosim {
namespace {

const std::string kTable2 = std::string(NCOSIM_SOURCE_DIR) + "/scenarios/dolz2014_table2.toml";

// Packets of 4096 periods drawn from the Table 2 links, replayed cyclically (stamps shifted).
struct Stream {
  std::unique_ptr<sim::Scenario> sc;
  std::vector<std::vector<est::Packet>> per_period;
};

Stream& stream() {
  static Stream s = [] {
    Stream st;
    st.sc = std::move(sim::load_cases(kTable2, {}).cases.front().scenario);
    const int periods = 4096;
    st.per_period.resize(periods);
    kernel::Rng rng = kernel::make_stream(1, 0, 0);
    for (std::size_t i = 0; i < st.sc->model.sensors.size(); ++i) {
      auto link = st.sc->model.sensors[i].link->clone();
      for (int k = 0; k < periods; ++k) {
        const auto d = link->transmit(rng);
        if (d == models::kLost || k + d >= periods) continue;
        est::Packet p;
        p.sensor = static_cast<int>(i);
        p.send_period = k;
        p.count = 1;
        p.stamps = {k};
        p.values = Eigen::VectorXd::Constant(1, 0.1 * (k % 7));
        st.per_period[static_cast<std::size_t>(k + d)].push_back(p);
      }
    }
    return st;
  }();
  return s;
}

void run_updates(benchmark::State& state, const std::string& name) {
  Stream& s = stream();
  const est::EstimatorDesign* design = nullptr;
  for (const auto& e : s.sc->estimators) {
    if (e.name == name) design = e.design.get();
  }
  auto est = design->instantiate();
  const Eigen::VectorXd u = Eigen::VectorXd::Zero(1), drive = Eigen::VectorXd::Constant(2, 0.01);
  const est::PeriodInput in{u, drive};
  std::int64_t k = 0;
  const auto n = static_cast<std::int64_t>(s.per_period.size());
  for (auto _ : state) {
    auto& arrivals = s.per_period[static_cast<std::size_t>(k % n)];
    const std::int64_t offset = k - k % n;
    for (auto& p : arrivals) {
      p.stamps[0] = p.send_period + offset;  // in place: the stream repeats shifted in time
      est->on_packet(p, k);
    }
    est->on_period(k, in);
    benchmark::DoNotOptimize(est->state().data());
    ++k;
  }
  state.SetItemsProcessed(state.iterations());
}

void BM_PeriodUpdate_OpenLoop(benchmark::State& s) { run_updates(s, "open loop"); }
void BM_PeriodUpdate_JumpS4N4(benchmark::State& s) { run_updates(s, "S4, 60 gains"); }
void BM_PeriodUpdate_JumpS1(benchmark::State& s) { run_updates(s, "S1, 1 gain"); }
void BM_PeriodUpdate_KalmanExtended(benchmark::State& s) { run_updates(s, "Kalman"); }
BENCHMARK(BM_PeriodUpdate_OpenLoop);
BENCHMARK(BM_PeriodUpdate_JumpS1);
BENCHMARK(BM_PeriodUpdate_JumpS4N4);
BENCHMARK(BM_PeriodUpdate_KalmanExtended);

// The model of filterpy's KalmanFilter timing (2-state constant velocity, one position sensor,
// ideal link): kalman_extended with max_delay 0, one packet every period.
void BM_PeriodUpdate_KalmanCv2(benchmark::State& state) {
  const std::string text = R"(
[plant]
kind = "lti"
A = [[1.0, 1.0], [0.0, 1.0]]
W = [[0.0025, 0.005], [0.005, 0.01]]
[[sensor]]
name = "pos"
C = [[1.0, 0.0]]
R = [[1.0]]
[[estimator]]
kind = "kalman_extended"
max_delay = 0
)";
  const auto sc =
      sim::build_scenario(toml::parse(text, std::string_view("cv2.toml")), "cv2.toml", ".");
  auto est = sc->estimators.front().design->instantiate();
  std::vector<double> zs(256);
  for (std::size_t i = 0; i < zs.size(); ++i)
    zs[i] = 0.5 * static_cast<double>(i) + std::sin(static_cast<double>(i));
  const Eigen::VectorXd u = Eigen::VectorXd::Zero(0), drive = Eigen::VectorXd::Zero(2);
  const est::PeriodInput in{u, drive};
  est::Packet p;
  p.sensor = 0;
  p.count = 1;
  p.stamps = {0};
  p.values = Eigen::VectorXd::Zero(1);
  std::int64_t k = 0;
  for (auto _ : state) {
    p.send_period = k;
    p.stamps[0] = k;
    p.values(0) = zs[static_cast<std::size_t>(k % 256)];
    est->on_packet(p, k);
    est->on_period(k, in);
    benchmark::DoNotOptimize(est->state().data());
    ++k;
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_PeriodUpdate_KalmanCv2);

void BM_DesignS4N4(benchmark::State& state) {
  const Stream& s = stream();
  const est::ExtendedModel ext = est::build_extended(s.sc->model, 1);
  for (auto _ : state) {
    const auto prob = est::pattern_probabilities(s.sc->model, ext);
    auto d = est::design_jump_iterative(ext, prob, 4, est::Grouping::kS4);
    benchmark::DoNotOptimize(d.P.data());
  }
}
BENCHMARK(BM_DesignS4N4)->Unit(benchmark::kMillisecond);

// The whole flagship scenario on one thread: 20 runs x 20000 periods x 7 estimators; with
// argument 1, also the run-averaged error curve ([run] error_curve = true, issue 28).
void BM_FlagshipScenario(benchmark::State& state) {
  const std::vector<std::string> sets = state.range(0) != 0
                                            ? std::vector<std::string>{"run.error_curve=true"}
                                            : std::vector<std::string>{};
  auto sc = std::move(sim::load_cases(kTable2, sets).cases.front().scenario);
  sim::CampaignOptions opt;
  opt.threads = 1;
  opt.time_estimators = false;
  for (auto _ : state) {
    auto r = sim::run_campaign(*sc, opt);
    benchmark::DoNotOptimize(r.runs.data());
  }
  state.SetItemsProcessed(state.iterations() * sc->run.runs * sc->run.periods *
                          static_cast<std::int64_t>(sc->estimators.size()));
  state.SetLabel("items = periods x runs x estimators");
}
BENCHMARK(BM_FlagshipScenario)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->Iterations(3);

}  // namespace
}  // namespace ncosim
