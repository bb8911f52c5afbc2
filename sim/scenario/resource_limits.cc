// sim/scenario/resource_limits.cc — resource estimates and limits (see limits.h).
#include "sim/scenario/resource_limits.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <mutex>
#include <thread>

#include "lmi/limits.h"

namespace ncosim::sim {

namespace {
ResourceLimits& storage() {
  static ResourceLimits l;
  return l;
}

// Memory kept per built case (its designed scenario) and a share of the document parsed for it:
// measured 18 KB per case (tests/cli/data/base.toml swept over 2000 seeds: 12 MB -> 48 MB peak
// RSS); the constants keep a margin of about 2.5x.
constexpr double kCaseBytes = 40e3;
constexpr double kCaseBytesPerTextByte = 2.0;

// Designs estimated above either of these get a note on stderr before they start.
constexpr double kNoteBytes = 256.0 * 1024 * 1024;
constexpr double kNoteFlops = 10e9;
// Effective rate of the design code (Table 2's S4 design at history 4, max_delay 7: an estimated
// 67 GFLOP in 56 s on a 2-core Zen 4 guest).
constexpr double kFlopsPerSecond = 1.2e9;

// Whole GFLOP from 100 on, else three significant digits (a limit of 0.01 GFLOP is not "0").
std::string gflop(double flops) {
  const double g = flops / 1e9;
  return g >= 100.0 ? fmt::format("{:.0f} GFLOP", g) : fmt::format("{:.3g} GFLOP", g);
}
}  // namespace

const ResourceLimits& resource_limits() { return storage(); }

void set_resource_limits(const ResourceLimits& limits) {
  storage() = limits;
  lmi::set_resource_limits({limits.memory_bytes, limits.work_flops});
}

std::string human_bytes(double bytes) {
  if (bytes >= 1e12) return fmt::format("{:.1f} TB", bytes / 1e12);
  if (bytes >= 1e9) return fmt::format("{:.1f} GB", bytes / 1e9);
  return fmt::format("{:.0f} MB", std::ceil(bytes / 1e6));
}

std::string state_driver(const config::Table& plant, const toml::table& raw,
                         const est::Model& model) {
  const auto n = model.plant.n();
  if (const toml::node* dt = raw.get("dead_time")) {
    const auto v = dt->value<double>();
    if (v && *v > 0.0) {
      return fmt::format("{} ({} s at run.period = {} s gives {} plant states)",
                         plant.key_path("dead_time"), *v, model.period, n);
    }
  }
  for (const char* key : {"A", "den", "modes"}) {
    if (raw.get(key) != nullptr) return fmt::format("{} ({} plant states)", plant.key_path(key), n);
  }
  return fmt::format("{} ({} plant states)", plant.path().empty() ? "plant" : plant.path(), n);
}

void check_estimator_resources(const config::Table& t, const std::string& kind,
                               const est::DesignCost& cost, const std::string& driver) {
  const ResourceLimits& lim = resource_limits();
  const double bytes = cost.bytes, flops = cost.flops;
  const std::string& key = cost.driver.empty() ? driver : cost.driver;
  if (lim.memory_bytes > 0.0 && bytes > lim.memory_bytes) {
    t.fail("kind", fmt::format("the {} design needs an estimated {}, above the memory limit of {} "
                               "(--max-memory); its size is driven by {}",
                               kind, human_bytes(bytes), human_bytes(lim.memory_bytes), key));
  }
  if (lim.work_flops > 0.0 && flops > lim.work_flops) {
    t.fail("kind", fmt::format("the {} design needs an estimated {}, above the work limit of {} "
                               "(--max-work); its size is driven by {}",
                               kind, gflop(flops), gflop(lim.work_flops), key));
  }
  if (bytes > kNoteBytes || flops > kNoteFlops) {
    // Within the limits but large: say so before minutes of silence (`check` included).
    std::cerr << fmt::format(
        "ncosim: note: {}: the {} design needs an estimated {} and {} (about {} s of one core); "
        "its size is driven by {}\n",
        t.key_path("kind"), kind, human_bytes(bytes), gflop(flops),
        static_cast<long>(std::ceil(flops / kFlopsPerSecond)), key);
  }
}

std::function<void(const lmi::SolveEstimate&)> large_solve_note(const config::Table& t,
                                                                const std::string& kind,
                                                                const std::string& driver) {
  return [noted = false, path = t.key_path("kind"), kind,
          driver](const lmi::SolveEstimate& e) mutable {
    if (noted || (e.bytes <= kNoteBytes && e.flops <= kNoteFlops)) return;
    noted = true;
    std::cerr << fmt::format(
        "ncosim: note: {}: the {} design solves an LMI problem of {} scalar variables (largest "
        "block {}) that needs an estimated {} and {} (about {} s of one core); its size is "
        "driven by {}\n",
        path, kind, e.variables, e.largest_block, human_bytes(e.bytes), gflop(e.flops),
        static_cast<long>(std::ceil(e.flops / kFlopsPerSecond)), driver);
  };
}

void check_network_work(const config::Table& t, const std::string& key, double seconds,
                        const std::string& what) {
  const ResourceLimits& lim = resource_limits();
  const double flops = seconds * kFlopsPerSecond;
  if (!(lim.work_flops > 0.0 && flops > lim.work_flops)) return;
  t.fail(key, fmt::format("the networks' simulation needs at least an estimated {} s of one core "
                          "({}), above the work limit of {} (--max-work, about {} s of one "
                          "core)",
                          static_cast<long long>(std::ceil(seconds)), what, gflop(lim.work_flops),
                          static_cast<long long>(std::ceil(lim.work_flops / kFlopsPerSecond))));
}

void check_network_memory(const config::Table& t, const std::string& key, double bytes,
                          const std::string& what) {
  const ResourceLimits& lim = resource_limits();
  if (!(lim.memory_bytes > 0.0 && bytes > lim.memory_bytes)) return;
  t.fail(key, fmt::format("the networks' simulation needs an estimated {} ({}), above the memory "
                          "limit of {} (--max-memory)",
                          human_bytes(bytes), what, human_bytes(lim.memory_bytes)));
}

void check_campaign_resources(const std::string& file, int line, std::int64_t runs,
                              std::size_t cases, std::size_t estimators, std::int64_t states,
                              std::size_t sensors) {
  const ResourceLimits& lim = resource_limits();
  // Per run and estimator: EstimatorRunMetrics (~300 bytes with its vectors) + per-state sums +
  // per-sensor counters; kept for every run until the tables are written.
  const double per =
      300.0 + 32.0 * static_cast<double>(states) + 96.0 * static_cast<double>(sensors);
  const double bytes = static_cast<double>(runs) * static_cast<double>(cases) *
                       static_cast<double>(estimators) * per;
  if (lim.memory_bytes > 0.0 && bytes > lim.memory_bytes) {
    throw config::ScenarioError(config::format_error(
        file, line, "run.runs",
        fmt::format("the campaign keeps per-run results of {} runs x {} case(s) x {} estimator(s): "
                    "an estimated {}, "
                    "above the memory limit of {} (--max-memory)",
                    runs, cases, estimators, human_bytes(bytes), human_bytes(lim.memory_bytes))));
  }
}

void CurveTotals::add(std::int64_t periods, std::size_t estimators, std::int64_t states) {
  const double ke = static_cast<double>(periods) * static_cast<double>(estimators);
  const double copy = 16.0 * ke * static_cast<double>(states + 1);
  const double csv = ke * (16.0 + 13.0 * static_cast<double>(states + 4));
  ++cases_;
  largest_ = std::max(largest_, copy);
  exports_ += copy + 2.0 * csv;
  last_copy_ = copy;
  last_shape_ =
      fmt::format("{} periods x {} estimator(s) x {} cells", periods, estimators, states + 1);
}

double CurveTotals::bytes() const {
  // Measured (peak RSS, /usr/bin/time -v, less the 40 MB of the same run without the curve;
  // tests/cli/data/base.toml: 2 estimators, 2 states): with S = 16 bytes x (states + 1) cells per
  // period and estimator (one copy of a curve), the peak is 4.9 S for one case (1 or 2 threads,
  // 200k to 1M periods) and 7.3 S for a sweep of 2 cases. Where it goes: one copy per worker thread
  // while the runs go (T S), 4 S while the curve is merged into the store (its copy, the blob and
  // SQLite's), then the exports: the campaign's curve, every case's curve read back, and
  // error_curve.csv built and copied once (1.3 S of text measured; bounded here by 13 bytes a
  // number and 16 for the labels: 2 S for 2 states).
  // The process around it (40 MB measured without the curve) is counted too, so that the estimate
  // bounds the peak RSS that --max-memory is about. Measured against the estimate (2 threads):
  // 140, 275 and 510 MB peak RSS at 200k, 500k and 1M periods for 178, 348 and 632 MB estimated
  // (1.27, 1.27, 1.24 times the peak); a sweep of 2 cases at 500k, 391 MB for 584 MB (1.49).
  constexpr double kProcessBytes = 64e6;
  const double threads = std::max(1U, std::thread::hardware_concurrency());
  return kProcessBytes + std::max(std::max(threads, 4.0) * largest_, largest_ + exports_);
}

void check_error_curve_resources(const std::string& file, int line, const std::string& key,
                                 const CurveTotals& totals) {
  if (totals.cases() == 0) return;
  const ResourceLimits& lim = resource_limits();
  if (totals.last_copy() > 9e8) {  // SQLite's largest blob is 1e9 bytes (SQLITE_MAX_LENGTH)
    throw config::ScenarioError(config::format_error(
        file, line, key,
        fmt::format("the error curve of {} is {}, above the run store's 900 MB for one case; "
                    "fewer periods, or error_curve = false",
                    totals.last_shape(), human_bytes(totals.last_copy()))));
  }
  const double bytes = totals.bytes();
  if (lim.memory_bytes > 0.0 && bytes > lim.memory_bytes) {
    throw config::ScenarioError(config::format_error(
        file, line, key,
        fmt::format(
            "the error curve of {}{} needs an estimated {} (a copy per worker thread "
            "while the runs go; for the exports every case's curve and its rows of "
            "error_curve.csv), above the memory limit of {} (--max-memory); fewer "
            "periods, or error_curve = false",
            totals.last_shape(),
            totals.cases() > 1 ? fmt::format(" (the last of {} cases)", totals.cases()) : "",
            human_bytes(bytes), human_bytes(lim.memory_bytes))));
  }
}

void check_trace_resources(const std::string& trace, int line, std::int64_t delay,
                           std::int64_t runs, const std::string& named_by) {
  const ResourceLimits& lim = resource_limits();
  // Per period of the largest delay: the per-run counts (8 bytes a run, and their serialised
  // copies in the store), the summed histogram and links.csv's rows: measured 65 and 165 bytes
  // (peak RSS) at 4 and 16 runs of tests/cli/data/base.toml with one delay of 10^7 periods; the
  // constants keep a margin of about 1.5x.
  constexpr double kBytesPerDelay = 48.0, kBytesPerDelayAndRun = 12.0;
  const double bytes = static_cast<double>(delay) *
                       (kBytesPerDelay + kBytesPerDelayAndRun *
                                             static_cast<double>(std::max<std::int64_t>(runs, 1)));
  if (lim.memory_bytes > 0.0 && bytes > lim.memory_bytes) {
    throw config::ScenarioError(config::format_error(
        trace, line, "",
        fmt::format(
            "delay: {} periods: the runs count delivered packets per delay up to the largest, an "
            "estimated "
            "{} for {} run(s), above the memory limit of {} (--max-memory) (the trace named by {})",
            delay, human_bytes(bytes), runs, human_bytes(lim.memory_bytes), named_by)));
  }
}

void check_sweep_resources(const std::string& file, int line, std::size_t cases,
                           std::size_t text_bytes) {
  const ResourceLimits& lim = resource_limits();
  const double bytes = static_cast<double>(cases) *
                       (kCaseBytes + kCaseBytesPerTextByte * static_cast<double>(text_bytes));
  if (lim.memory_bytes > 0.0 && bytes > lim.memory_bytes) {
    throw config::ScenarioError(config::format_error(
        file, line, "sweep",
        fmt::format("{} sweep cases need an estimated {} (each case is designed and "
                    "kept), above the memory limit "
                    "of {} (--max-memory)",
                    cases, human_bytes(bytes), human_bytes(lim.memory_bytes))));
  }
}

}  // namespace ncosim::sim
