// bench/links_bench.cc — what links.csv costs on the flagship campaign (bench/README.md,
// "links.csv"): every run of scenarios/dolz2014_table2.toml simulated on one thread with the
// link counters off and on, alternating run by run in one process (so that a load change on a
// shared machine hits both alike), each run's record serialized as the run store does
// (serialize_run; serialize_links when counted); and the derivation of links.csv from the stored
// counters (deserialize every run's, sum, format), against the same campaign.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <vector>

#include "sim/run/campaign.h"
#include "sim/run/link_report.h"
#include "sim/scenario/scenario.h"
#include "sim/store/store.h"

namespace ncosim {
namespace {

using Clock = std::chrono::steady_clock;

const sim::LoadedScenario& flagship() {
  static const sim::LoadedScenario loaded =
      sim::load_cases(std::string(NCOSIM_SOURCE_DIR) + "/scenarios/dolz2014_table2.toml", {});
  return loaded;
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n == 0 ? 0.0 : (n % 2 == 1 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]));
}

// One iteration = the whole campaign twice (counters off, on), run by run in alternating order.
// Counters: off_s / on_s (median campaign seconds), share_pct (median over the iterations of
// 100 (on - off) / off).
void BM_LinkCountersShare(benchmark::State& state) {
  const sim::Scenario& sc = *flagship().cases.front().scenario;
  std::vector<double> off_s, on_s, share;
  std::int64_t iteration = 0;
  for (auto _ : state) {
    double off = 0.0, on = 0.0;
    for (std::int64_t r = 0; r < sc.run.runs; ++r) {
      for (std::int64_t pass = 0; pass < 2; ++pass) {
        const bool count = (pass + r + iteration) % 2 == 0;  // which goes first alternates
        const auto t0 = Clock::now();
        sim::RunLinks links;
        const sim::RunMetrics m = sim::simulate_run(sc, static_cast<std::uint64_t>(r), nullptr,
                                                    nullptr, count ? &links : nullptr);
        std::string blob = sim::serialize_run(m);
        if (count) blob += sim::serialize_links(links);
        benchmark::DoNotOptimize(blob.data());
        const double s = std::chrono::duration<double>(Clock::now() - t0).count();
        (count ? on : off) += s;
      }
    }
    off_s.push_back(off);
    on_s.push_back(on);
    share.push_back(100.0 * (on - off) / off);
    ++iteration;
  }
  state.counters["off_s"] = median(off_s);
  state.counters["on_s"] = median(on_s);
  state.counters["share_pct"] = median(share);
}
BENCHMARK(BM_LinkCountersShare)->Unit(benchmark::kMillisecond)->Iterations(15);

// links.csv from the stored counters of the flagship's runs: deserialize, sum, format.
void BM_LinksCsvDerivation(benchmark::State& state) {
  const sim::LoadedScenario& loaded = flagship();
  const sim::Scenario& sc = *loaded.cases.front().scenario;
  std::vector<std::string> blobs;
  for (std::int64_t r = 0; r < sc.run.runs; ++r) {
    sim::RunLinks links;
    sim::simulate_run(sc, static_cast<std::uint64_t>(r), nullptr, nullptr, &links);
    blobs.push_back(sim::serialize_links(links));
  }
  for (auto _ : state) {
    sim::CampaignResult res;
    for (const auto& b : blobs) res.link_runs.push_back(sim::deserialize_links(b));
    const std::string csv =
        sim::links_csv(loaded.sweeps, {loaded.cases.front().labels}, {&sc}, {&res});
    benchmark::DoNotOptimize(csv.data());
  }
}
BENCHMARK(BM_LinksCsvDerivation)->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace ncosim
