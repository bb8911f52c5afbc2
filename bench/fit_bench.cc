// bench/fit_bench.cc — `ncosim fit`: the hidden two-state Gilbert–Elliott fit (Baum–Welch from
// the default starts, to convergence, without and with the Wald intervals) on 10^6 packets; and
// the cost of links.csv's per-packet counters on the flagship campaign (every run of
// scenarios/dolz2014_table2.toml on one thread, without (0) and with (1) the counters).
#include <benchmark/benchmark.h>

#include "kernel/rng.h"
#include "models/fit.h"
#include "models/link.h"
#include "sim/run/campaign.h"
#include "sim/scenario/scenario.h"

namespace ncosim {
namespace {

std::vector<int> ge_trace(int n) {
  auto link = models::make_gilbert_elliott(0.02, 0.15, 0.02, 0.6);
  kernel::Rng rng = kernel::make_stream(1, 0, 0);
  link->reset(rng);
  std::vector<int> sym;
  sym.reserve(static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) sym.push_back(link->transmit(rng) == models::kLost ? 0 : 1);
  return sym;
}

void BM_FitGilbertElliott(benchmark::State& state) {
  const std::vector<int> sym = ge_trace(static_cast<int>(state.range(0)));
  models::FitOptions o;
  o.intervals = state.range(1) != 0;
  int iterations = 0;
  for (auto _ : state) {
    const models::FitResult r = models::fit_family("gilbert_elliott", sym, o);
    iterations = r.iterations;
    benchmark::DoNotOptimize(r.loglik);
  }
  state.counters["em_iterations"] = iterations;
}
BENCHMARK(BM_FitGilbertElliott)
    ->Args({1000000, 0})
    ->Args({1000000, 1})
    ->Unit(benchmark::kMillisecond);

void BM_FlagshipLinkCounters(benchmark::State& state) {
  auto sc = std::move(
      sim::load_cases(std::string(NCOSIM_SOURCE_DIR) + "/scenarios/dolz2014_table2.toml", {})
          .cases.front()
          .scenario);
  const bool count = state.range(0) != 0;
  for (auto _ : state) {
    for (std::int64_t r = 0; r < sc->run.runs; ++r) {
      std::vector<models::LinkCounters> links;
      auto m = sim::simulate_run(*sc, static_cast<std::uint64_t>(r), nullptr, nullptr,
                                 count ? &links : nullptr);
      benchmark::DoNotOptimize(m.data());
      benchmark::DoNotOptimize(links.data());
    }
  }
}
BENCHMARK(BM_FlagshipLinkCounters)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->Iterations(3);

}  // namespace
}  // namespace ncosim
