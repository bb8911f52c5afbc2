// sim/scenario/resource_limits.cc — resource estimates and limits (see limits.h).
#include "sim/scenario/resource_limits.h"

#include <fmt/format.h>

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

// An integer key read without marking it known (the estimator's own reader validates it).
std::int64_t peek_integer(const toml::table& t, std::string_view key, std::int64_t fallback) {
  const toml::node* n = t.get(key);
  if (n == nullptr) return fallback;
  if (auto i = n->value_exact<std::int64_t>()) return *i;
  if (auto d = n->value_exact<double>()) {
    if (std::isfinite(*d) && std::floor(*d) == *d && std::fabs(*d) < 1e9)
      return static_cast<std::int64_t>(*d);
  }
  return fallback;
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

std::string state_driver(const Table& plant, const toml::table& raw, const est::Model& model) {
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

void check_estimator_resources(const Table& t, const toml::table& raw, const std::string& kind,
                               const est::Model& model, const std::string& driver) {
  const ResourceLimits& lim = resource_limits();
  const double n = static_cast<double>(model.plant.n());
  const double ny = static_cast<double>(model.total_outputs());
  const double sensors = static_cast<double>(model.sensors.size());
  const std::int64_t dbar =
      std::max<std::int64_t>(0, std::min<std::int64_t>(peek_integer(raw, "max_delay", 0), 62));
  const std::int64_t history =
      std::max<std::int64_t>(1, std::min<std::int64_t>(peek_integer(raw, "history", 1), 1000));
  // The state the design iterates on: the plant, or the plant with its delay line.
  double dim = n;
  std::string key = driver;
  if (kind == "kalman_extended" || kind == "static_buffer" || kind == "kalman_buffer") {
    dim = n * static_cast<double>(dbar + 1) + ny * static_cast<double>(dbar);
    if (dbar > 0) key = fmt::format("{} (with {})", t.key_path("max_delay"), driver);
  }
  // Riccati / Lyapunov iterations on dim x dim matrices: ~16 matrices, ~200 products.
  double bytes = 16.0 * 8.0 * dim * dim;
  double flops = 200.0 * 2.0 * dim * dim * dim;
  if (kind == "jump") {
    // history x 2^(fictitious sensors) terms, each with gains n x (fictitious outputs) and an
    // update of the n x n covariance, over ~50 iterations. Memory per term: about two nyf x nyf
    // matrices besides the gain and covariance (measured on Table 2's A3 with S4: 1.9, 3.1 and
    // 4.3 kB per term at nyf = 12, 14, 16, i.e. max_delay 5, 6, 7; 1.1 GB at history 4,
    // max_delay 7, where this formula gives 1.2 GB).
    const double nf = sensors * static_cast<double>(dbar + 1);
    const double terms =
        static_cast<double>(history) * std::ldexp(1.0, static_cast<int>(std::min(nf, 60.0)));
    const double nyf = ny * static_cast<double>(dbar + 1);
    bytes += terms * 8.0 * (2.0 * nyf * nyf + 2.0 * n * nyf + 2.0 * n * n);
    flops += 50.0 * terms * (2.0 * n * n * n + 2.0 * n * nyf * nyf + nyf * nyf * nyf);
    key = fmt::format("{} and {} ({} x 2^{} terms, {})", t.key_path("history"),
                      t.key_path("max_delay"), history, nf, driver);
  }
  if (kind == "static_buffer" && n <= 7.0) {
    // The fourth-moment radius of the oldest slot's recursion (estimators/design/buffer_design.cc,
    // n <= 7): E[F^{x4}] is an n^4 x n^4 matrix, one dense product per sensor, then an eigenvalue
    // solve (~6 products: 89 s for n = 7 and one sensor on a 2-core Zen 4 guest, where this
    // formula gives 10 products, 1.4e11 flops). Five states and 1001 sensors: about 7 minutes.
    const double big = n * n * n * n;
    bytes += 8.0 * 4.0 * big * big;
    flops += (2.0 * sensors + 8.0) * big * big * big;
    key = fmt::format(
        "{} and the {} sensor(s) (the fourth-moment operator is {:.0f} x {:.0f}, one product per "
        "sensor)",
        driver, sensors, big, big);
  }
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

std::function<void(const lmi::SolveEstimate&)> large_solve_note(const Table& t,
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
    throw ScenarioError(format_error(
        file, line, "run.runs",
        fmt::format("the campaign keeps per-run results of {} runs x {} case(s) x {} estimator(s): "
                    "an estimated {}, "
                    "above the memory limit of {} (--max-memory)",
                    runs, cases, estimators, human_bytes(bytes), human_bytes(lim.memory_bytes))));
  }
}

void check_error_curve_resources(const std::string& file, int line, std::int64_t periods,
                                 std::size_t estimators, std::int64_t states) {
  const ResourceLimits& lim = resource_limits();
  // 16 bytes a cell (a compensated sum: hi and lo), n + 1 cells per period and estimator, in one
  // copy per worker thread plus the merged one and the stored one it is added to.
  const double copies =
      static_cast<double>(std::max(1U, std::thread::hardware_concurrency())) + 2.0;
  const double bytes = 16.0 * static_cast<double>(periods) * static_cast<double>(estimators) *
                       static_cast<double>(states + 1) * copies;
  const double blob = 16.0 * static_cast<double>(periods) * static_cast<double>(estimators) *
                      static_cast<double>(states + 1);
  if (blob > 9e8) {  // SQLite's largest blob is 1e9 bytes (SQLITE_MAX_LENGTH)
    throw ScenarioError(format_error(
        file, line, "run.error_curve",
        fmt::format("the error curve of {} periods x {} estimator(s) x {} cells is {}, "
                    "above the run store's 900 MB for one case; fewer periods, or "
                    "error_curve = false",
                    periods, estimators, states + 1, human_bytes(blob))));
  }
  if (lim.memory_bytes > 0.0 && bytes > lim.memory_bytes) {
    throw ScenarioError(
        format_error(file, line, "run.error_curve",
                     fmt::format("the error curve keeps {} periods x {} estimator(s) x {} cells in "
                                 "{:.0f} copies (one per thread, "
                                 "their sum, the stored one): an estimated {}, above the memory "
                                 "limit of {} (--max-memory); "
                                 "fewer periods, or error_curve = false",
                                 periods, estimators, states + 1, copies, human_bytes(bytes),
                                 human_bytes(lim.memory_bytes))));
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
    throw ScenarioError(format_error(
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
    throw ScenarioError(
        format_error(file, line, "sweep",
                     fmt::format("{} sweep cases need an estimated {} (each case is designed and "
                                 "kept), above the memory limit "
                                 "of {} (--max-memory)",
                                 cases, human_bytes(bytes), human_bytes(lim.memory_bytes))));
  }
}

}  // namespace ncosim::sim
