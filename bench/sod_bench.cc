// bench/sod_bench.cc — send-on-delta designs of example 5.1 (send-on-delta co-design paper):
// one LMI problem (11) and (20), z~0, and whole greedy co-designs (C1 and C3 at mu = 1.2), against
// the paper's 1.7 s per LMI and about 70 s per co-design (MATLAB, i7-3770).
#include <benchmark/benchmark.h>

#include "estimators/design/sod_bounds.h"
#include "estimators/design/sod_design.h"

namespace ncosim {
namespace {

using namespace est::sod;

SodSystem example51() {
  SodSystem s;
  s.A.resize(3, 3);
  s.A << 1.005, 0.221, 0.171, -0.031, 1.008, 0.136, 0.049, 0.038, 1.028;
  s.Bw.resize(3, 2);
  s.Bw << -0.229, 0.023, 0.231, 0.211, -0.186, 0.245;
  s.C.resize(2, 3);
  s.C << 0.519, -0.233, 0.095, 0.569, 0, 0;
  s.Cz = Eigen::MatrixXd::Identity(3, 3);
  s.sensor_rows = {0, 1, 2};
  s.w_rms = 0.468;
  s.v_rms = Eigen::Vector2d(0.032, 0.032);
  return s;
}

void BM_SodLmi(benchmark::State& state) {
  const SodSystem s = example51();
  SodDesignSpec spec;
  spec.approach = state.range(0) == 0 ? Approach::kDeterministic : Approach::kStochastic;
  spec.jump = true;
  const Eigen::Vector2d d(0.236, 0.098), r(0.9, 0.75);
  for (int i = 0; i < 2; ++i) {
    spec.sigma2_delta.resize(2);
    spec.beta_lower.resize(2);
    spec.sigma2_delta(i) =
        spec.approach == Approach::kDeterministic ? d(i) * d(i) / 3 : uniform_sigma2(d(i), r(i));
    spec.beta_lower(i) = uniform_beta(d(i), r(i));
  }
  SodDesignResult res;
  for (auto _ : state) {
    res = design_sod(s, spec);
    benchmark::DoNotOptimize(res.bound);
  }
  state.counters["lmis"] = res.lmis;
  state.counters["sdp_dimension"] = res.size.total_dimension;
  state.counters["sdp_variables"] = res.size.variables;
  state.SetLabel(spec.approach == Approach::kDeterministic ? "LMI (11), 16 blocks"
                                                           : "LMI (20), 4 vertices");
}
BENCHMARK(BM_SodLmi)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_SodZ0(benchmark::State& state) {
  const SodSystem s = example51();
  for (auto _ : state) benchmark::DoNotOptimize(design_all_measurements(s).bound);
}
BENCHMARK(BM_SodZ0)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_SodCodesign(benchmark::State& state) {
  const SodSystem s = example51();
  CodesignSpec spec;
  spec.r = Eigen::Vector2d(0.9, 0.75);
  spec.target = 1.2 * design_all_measurements(s).bound;
  spec.delta0 = 0.01 * spec.r;
  if (state.range(0) == 0) {  // C1: deterministic jump, sigma^2 = Delta^2/3, 2 % relative steps
    spec.approach = Approach::kDeterministic;
    spec.sigma2_factor = 1.0 / 3.0;
    spec.relative_step = true;
    spec.epsilon = 0.02;
  } else {  // C3: stochastic jump, all vertices, absolute steps of 0.005
    spec.approach = Approach::kStochastic;
    spec.epsilon = 0.005;
  }
  CodesignResult r;
  for (auto _ : state) {
    r = codesign(s, spec);
    benchmark::DoNotOptimize(r.cost);
  }
  state.counters["lmi_problems"] = r.lmi_problems;
  state.counters["per_lmi_ms"] = 1e3 * r.lmi_seconds / r.lmi_problems;
  state.SetLabel(state.range(0) == 0 ? "C1, mu = 1.2" : "C3, mu = 1.2");
}
BENCHMARK(BM_SodCodesign)
    ->Arg(0)
    ->Arg(1)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->Iterations(3);

}  // namespace
}  // namespace ncosim
