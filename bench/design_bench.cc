// bench/design_bench.cc — design time of the jump observer gains per method and size
// (system A3 of Dolz et al. 2014, Table 2 links, dbar = 1): iterative against the paper's CCL
// (estimators/design/ccl_design.h), and the CCL as printed in the paper (BM_DesignCclLiteral,
// N̄ = 1) as the baseline of ncosim's CCL. Arguments: grouping (1..4), Nbar. The CCL runs are
// heavy (a bisection of CCL loops of SDPs): one iteration each. Counters: the SDP size of a
// CCL step.
#include <benchmark/benchmark.h>

#include "estimators/design/ccl_design.h"
#include "estimators/design/jump_design.h"
#include "estimators/extended_model.h"
#include "sim/scenario/registries.h"
#include "sim/scenario/scenario.h"

namespace ncosim {
namespace {

struct A3 {
  std::unique_ptr<sim::Scenario> sc;
  est::ExtendedModel ext;
  std::vector<double> prob;
};

const A3& a3() {
  static A3 a = [] {
    A3 x;
    x.sc = std::move(
        sim::load_cases(std::string(NCOSIM_SOURCE_DIR) + "/scenarios/dolz2014_table2.toml", {})
            .cases.front()
            .scenario);
    x.ext = est::build_extended(x.sc->model, 1);
    x.prob = est::pattern_probabilities(x.sc->model, x.ext);
    return x;
  }();
  return a;
}

void BM_DesignIterative(benchmark::State& state) {
  const auto& a = a3();
  const auto g = static_cast<est::Grouping>(state.range(0) - 1);
  const int Nbar = static_cast<int>(state.range(1));
  double tr = 0.0;
  for (auto _ : state) {
    auto d = est::design_jump_iterative(a.ext, a.prob, Nbar, g);
    tr = d.Pt.trace();
    benchmark::DoNotOptimize(d);
  }
  state.counters["trPt"] = tr;
}

// The CCL design as printed in the paper (the baseline of BM_DesignCcl): a new feasible point
// at every bisection step, k_max = 20 iterations, the lower end at the LMI relaxation.
est::CclOptions literal_ccl() {
  est::CclOptions o;
  o.start = est::CclStart::kFeasible;
  o.patience = o.max_ccl_iterations;
  o.s4_bound = false;
  return o;
}

void DesignCcl(benchmark::State& state, const est::CclOptions& options) {
  const auto& a = a3();
  const auto g = static_cast<est::Grouping>(state.range(0) - 1);
  const int Nbar = static_cast<int>(state.range(1));
  est::CclInfo info;
  double tr = 0.0;
  for (auto _ : state) {
    auto d = est::design_jump_ccl(a.ext, a.prob, Nbar, g, options, &info);
    tr = d.stable ? d.Pt.trace() : -1.0;
    benchmark::DoNotOptimize(d);
  }
  state.counters["trPt"] = tr;
  state.counters["sdp_vars"] = info.size.variables;
  state.counters["sdp_blocks"] = info.size.blocks;
  state.counters["sdp_dim"] = info.size.total_dimension;
  state.counters["sdp_solves"] = info.sdp_solves;
}

void BM_DesignCcl(benchmark::State& state) { DesignCcl(state, {}); }
void BM_DesignCclLiteral(benchmark::State& state) { DesignCcl(state, literal_ccl()); }

void Sizes(benchmark::internal::Benchmark* b, int max_nbar) {
  for (int g = 1; g <= 4; ++g)
    for (int n = 1; n <= max_nbar; ++n) b->Args({g, n});
}

BENCHMARK(BM_DesignIterative)->Apply([](auto* b) { Sizes(b, 7); }) -> Unit(benchmark::kMillisecond);
BENCHMARK(BM_DesignCcl)
    ->Apply([](auto* b) { Sizes(b, 7); }) -> Unit(benchmark::kMillisecond) -> Iterations(1);
BENCHMARK(BM_DesignCclLiteral)
    ->Apply([](auto* b) { Sizes(b, 1); }) -> Unit(benchmark::kMillisecond) -> Iterations(1);

}  // namespace
}  // namespace ncosim
