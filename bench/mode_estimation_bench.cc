// bench/mode_estimation_bench.cc — per-period cost of the mode estimators on the CSTR model of
// Moayedi et al.: imm with 2, 4 and 8 modes (1, 2, 3 lossy inputs: the CSTR's two input
// columns and their sum as a third), Algorithm 1 (mode_io) and Algorithm 2 (mode_ss) with 4.
// The baseline in the same process is the plant's Kalman filter (kalman_extended, max_delay 0).
#include <benchmark/benchmark.h>

#include <cmath>
#include <memory>
#include <string>

#include "kernel/rng.h"
#include "sim/scenario/scenario.h"

namespace ncosim {
namespace {

std::unique_ptr<sim::Scenario> cstr(int inputs, const std::string& kind) {
  const char* bu[] = {"[[0.011], [-0.3602]]", "[[0.011, -0.0014], [-0.3602, 0.4732]]",
                      "[[0.011, -0.0014, 0.0096], [-0.3602, 0.4732, 0.113]]"};
  std::string text = R"(
[plant]
A = [[-0.8882, -0.0097], [293.8556, 2.2973]]
Bu = )" + std::string(bu[inputs - 1]) +
                     R"(
W = [[0.0, 0.0], [0.0, 0.0]]
[input]
kind = "white"
std = 10.0
[[sensor]]
C = [[1.0, 0.0], [0.0, 1.0]]
R = [[2.5e-3, 0.0], [0.0, 2.5e-3]]
[[link]]
name = "act"
kind = "markov"
transition = [[0.8, 0.2], [0.4, 0.6]]
loss = [0.0, 1.0]
)";
  if (kind != "kalman_extended") {
    for (int i = 0; i < inputs; ++i) text += "[[actuator]]\nlink = \"act\"\non_loss = \"hold\"\n";
  }
  text += "[[estimator]]\nkind = \"" + kind + "\"\nP0 = [[0.1, 0.0], [0.0, 0.1]]\n";
  return sim::build_scenario(toml::parse(text, std::string_view("bench.toml")), "bench.toml", ".");
}

// One period: the packet of y[k] (values from a fixed table), then the update with u[k-1].
void run(benchmark::State& state, int inputs, const std::string& kind) {
  const auto sc = cstr(inputs, kind);
  auto est = sc->estimators.front().design->instantiate();
  std::vector<Eigen::VectorXd> ys, us, drives;
  for (int i = 0; i < 256; ++i) {
    ys.push_back(Eigen::Vector2d(0.5 * std::sin(i), 100.0 * std::cos(0.7 * i)));
    us.push_back(Eigen::VectorXd::Constant(inputs, 10.0 * std::sin(1.3 * i)));
    drives.push_back(sc->model.plant.Bu * us.back());  // outside the timed loop
  }
  const Eigen::VectorXd drive = Eigen::VectorXd::Zero(2);
  est::Packet p;
  p.sensor = 0;
  p.count = 1;
  p.stamps = {0};
  p.values = Eigen::VectorXd::Zero(2);
  std::int64_t k = 0;
  for (auto _ : state) {
    const auto i = static_cast<std::size_t>(k % 256);
    p.send_period = k;
    p.stamps[0] = k;
    p.values = ys[i];
    est->on_packet(p, k);
    est->on_period(k, est::PeriodInput{us[i], kind == "kalman_extended" ? drives[i] : drive});
    benchmark::DoNotOptimize(est->state().data());
    ++k;
  }
  state.SetItemsProcessed(state.iterations());
}

void BM_ModePeriod_KalmanBaseline(benchmark::State& s) { run(s, 2, "kalman_extended"); }
void BM_ModePeriod_Imm2(benchmark::State& s) { run(s, 1, "imm"); }
void BM_ModePeriod_Imm4(benchmark::State& s) { run(s, 2, "imm"); }
void BM_ModePeriod_Imm8(benchmark::State& s) { run(s, 3, "imm"); }
void BM_ModePeriod_Alg1ModeIo4(benchmark::State& s) { run(s, 2, "mode_io"); }
void BM_ModePeriod_Alg2ModeSs4(benchmark::State& s) { run(s, 2, "mode_ss"); }
BENCHMARK(BM_ModePeriod_KalmanBaseline);
BENCHMARK(BM_ModePeriod_Imm2);
BENCHMARK(BM_ModePeriod_Imm4);
BENCHMARK(BM_ModePeriod_Imm8);
BENCHMARK(BM_ModePeriod_Alg1ModeIo4);
BENCHMARK(BM_ModePeriod_Alg2ModeSs4);

}  // namespace
}  // namespace ncosim
