// bench/compare_bench.cc — `ncosim compare` end to end in process: read two folders (manifest.json,
// runs.csv), match and test every row, format compare.csv and compare.md. One item = one row
// compared.
#include <benchmark/benchmark.h>

#include <filesystem>
#include <fstream>
#include <random>

#include "sim/analysis/compare.h"

namespace {

namespace fs = std::filesystem;

// The committed flagship folder (Table 2: 7 rows x 20 runs).
const std::string kFlagship = std::string(NCOSIM_SOURCE_DIR) + "/results/dolz2014_table2";

void compare_once(benchmark::State& state, const std::string& base, const std::string& fresh) {
  std::size_t rows = 0;
  for (auto _ : state) {
    ncosim::sim::CompareOptions o;
    const auto b = ncosim::sim::read_run_folder(base, o.metric);
    const auto n = ncosim::sim::read_run_folder(fresh, o.metric);
    const auto r = ncosim::sim::compare_folders(b, n, o);
    const std::string csv = ncosim::sim::compare_csv(r), md = ncosim::sim::compare_markdown(r);
    benchmark::DoNotOptimize(csv.data());
    benchmark::DoNotOptimize(md.data());
    rows = r.rows.size();
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * rows));
  state.counters["rows"] = static_cast<double>(rows);
}

void BM_CompareFlagship(benchmark::State& state) { compare_once(state, kFlagship, kFlagship); }
BENCHMARK(BM_CompareFlagship)->Unit(benchmark::kMillisecond);

// A synthetic sweep folder: C cases x 7 estimators x 100 runs (C = 100: 70 000 runs.csv rows).
std::string synthetic(int cases, const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("ncosim_compare_bench_" + name);
  fs::create_directories(dir);
  std::ofstream(dir / "manifest.json")
      << R"({"scenario": "s.toml", "scenario_hash": "h", "seed": 1})";
  std::ofstream out(dir / "runs.csv");
  out << "link[0].delivery,run,estimator,mse,mse_ext,periods,samples_used,samples_taken,diverged,"
         "status,flops_mean,"
         "late_samples,duplicate_samples,mde_percent,rmse_x1,rmse_x2\n";
  std::mt19937_64 g(1);
  std::uniform_real_distribution<double> u(0.02, 0.05);
  for (int c = 0; c < cases; ++c) {
    for (int r = 0; r < 100; ++r) {
      for (int e = 0; e < 7; ++e) {
        out << 0.5 + 0.001 * c << "," << r << ",\"est " << e << "\"," << u(g) << "," << u(g)
            << ",19500,26603,39000,0,ok,,,,,0.3,0.07\n";
      }
    }
  }
  return dir.string();
}

void BM_CompareSweep100Cases(benchmark::State& state) {
  static const std::string a = synthetic(100, "a");
  compare_once(state, a, a);
}
BENCHMARK(BM_CompareSweep100Cases)->Unit(benchmark::kMillisecond);

}  // namespace
