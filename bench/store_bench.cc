// bench/store_bench.cc — the run store's cost per run (bench/README.md, "Run store"): the
// serialization of one flagship run (5 estimators, 2 sensors) and commits of batches of such
// runs (with their link counters) to runs.sqlite (WAL, synchronous=FULL: each commit waits for the
// disk), against the simulation of one flagship run.
#include <benchmark/benchmark.h>
#include <unistd.h>

#include <filesystem>

#include "sim/run/campaign.h"
#include "sim/scenario/scenario.h"
#include "sim/store/store.h"

namespace {

using namespace ncosim::sim;

const std::string kFlagship = std::string(NCOSIM_SOURCE_DIR) + "/scenarios/dolz2014_table2.toml";

const LoadedScenario& flagship() {
  static const LoadedScenario loaded = load_cases(kFlagship, {});
  return loaded;
}

const RunMetrics& flagship_run() {
  static const RunMetrics m = simulate_run(*flagship().cases.front().scenario, 0);
  return m;
}

// Its link counters (2 flows), committed with it as a campaign does.
const RunLinks& flagship_links() {
  static const RunLinks l = [] {
    RunLinks links;
    simulate_run(*flagship().cases.front().scenario, 0, nullptr, nullptr, &links);
    return links;
  }();
  return l;
}

void BM_SerializeRun(benchmark::State& state) {
  const RunMetrics& m = flagship_run();
  for (auto _ : state) {
    std::string blob = serialize_run(m);
    benchmark::DoNotOptimize(blob);
    benchmark::DoNotOptimize(deserialize_run(blob));
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_SerializeRun);

// Commits of `batch` runs each (one transaction per commit), per run.
void BM_StoreCommit(benchmark::State& state) {
  const auto batch = static_cast<std::size_t>(state.range(0));
  const auto dir =
      std::filesystem::temp_directory_path() / ("ncosim_store_bench_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  RunStore store = RunStore::create(store_path(dir.string()), {{"scenario_text", flagship().text}});
  std::uint64_t next = 0;
  std::vector<StoredRun> runs(batch);
  for (auto _ : state) {
    for (auto& r : runs) r = StoredRun{0, next++, flagship_run(), flagship_links()};
    store.put_runs(runs);
  }
  store.close();
  std::filesystem::remove_all(dir);
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(batch));
}
BENCHMARK(BM_StoreCommit)->Arg(1)->Arg(16)->Arg(128)->UseRealTime();

// One flagship run (20 000 periods, 5 estimators): the time the store's cost is compared with.
void BM_FlagshipRun(benchmark::State& state) {
  const Scenario& sc = *flagship().cases.front().scenario;
  std::uint64_t r = 0;
  for (auto _ : state) benchmark::DoNotOptimize(simulate_run(sc, r++));
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_FlagshipRun)->Unit(benchmark::kMillisecond);

}  // namespace
