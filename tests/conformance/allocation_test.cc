// tests/conformance/allocation_test.cc — no estimator allocates on its per-period path.
// Every registered estimator kind, on the conformance scenario of every link kind (and with
// sensors that buffer two samples per packet), is fed 2400 periods of packets; after 400
// periods of warm-up the heap allocations made by on_packet, on_period and the accessors
// (state, extended, covariance, mode, counters) must be zero.
//
// Counting: this binary replaces the global operator new / delete (the standard library's
// containers) and is linked with --wrap=malloc,calloc,realloc (tests/CMakeLists.txt), which
// catches Eigen's allocations (Eigen calls malloc directly) in every object linked statically
// into it: the project's libraries and this test. Both forward to the real allocator (or the
// sanitizer's, under ASan), so the binary runs unchanged otherwise.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <new>
#include <random>
#include <string>
#include <vector>

#include "conformance/fixtures.h"
#include "kernel/rng.h"
#include "sim/run/campaign.h"
#include "sim/scenario/registries.h"
#include "test_util.h"

namespace {
bool g_counting = false;
long g_allocations = 0;
void count() {
  if (g_counting) ++g_allocations;
}
}  // namespace

extern "C" {
void* __real_malloc(std::size_t size);
void* __real_calloc(std::size_t n, std::size_t size);
void* __real_realloc(void* p, std::size_t size);
void* __wrap_malloc(std::size_t size) {
  count();
  return __real_malloc(size);
}
void* __wrap_calloc(std::size_t n, std::size_t size) {
  count();
  return __real_calloc(n, size);
}
void* __wrap_realloc(void* p, std::size_t size) {
  count();
  return __real_realloc(p, size);
}
}

namespace {
void* counted_new(std::size_t size) {
  count();
  if (void* p = __real_malloc(size == 0 ? 1 : size)) return p;
  throw std::bad_alloc();
}
}  // namespace

void* operator new(std::size_t size) { return counted_new(size); }
void* operator new[](std::size_t size) { return counted_new(size); }
void* operator new(std::size_t size, const std::nothrow_t&) noexcept {
  count();
  return __real_malloc(size == 0 ? 1 : size);
}
void* operator new[](std::size_t size, const std::nothrow_t&) noexcept {
  count();
  return __real_malloc(size == 0 ? 1 : size);
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }
void operator delete(void* p, const std::nothrow_t&) noexcept { std::free(p); }
void operator delete[](void* p, const std::nothrow_t&) noexcept { std::free(p); }

namespace ncosim::sim {
namespace {

using namespace conformance;  // NOLINT: the suite's fixtures

// Packets of every sensor of `sc` over `periods` periods, per arrival period, drawn from the
// scenario's links: each sample carries the newest `buffer + 1` samples of its sensor.
std::vector<std::vector<est::Packet>> packets(const Scenario& sc, int periods) {
  std::vector<std::vector<est::Packet>> out(static_cast<std::size_t>(periods));
  kernel::Rng rng = kernel::make_stream(11, 0, 0);
  std::normal_distribution<double> normal;
  for (std::size_t i = 0; i < sc.model.sensors.size(); ++i) {
    const auto& spec = sc.model.sensors[i].spec;
    auto link = sc.model.sensors[i].link->clone();
    link->reset(rng);
    const Eigen::Index ny = spec.ny();
    for (int k = 0; k < periods; ++k) {
      const auto d = link->transmit(rng);
      if (d == models::kLost || k + d >= periods) continue;
      est::Packet p;
      p.sensor = static_cast<int>(i);
      p.send_period = k;
      p.count = std::min(spec.buffer + 1, k + 1);
      p.values.resize(p.count * ny);
      for (int c = 0; c < p.count; ++c) {
        p.stamps.push_back(k - c);
        for (Eigen::Index r = 0; r < ny; ++r) p.values(c * ny + r) = normal(rng);
      }
      out[static_cast<std::size_t>(k + d)].push_back(std::move(p));
    }
  }
  return out;
}

// Allocations of each estimator of `sc` over the counted periods (after the warm-up).
void expect_no_allocation(const Scenario& sc, const std::string& what) {
  constexpr int kWarmup = 400, kPeriods = 2400;
  const auto arrivals = packets(sc, kPeriods);
  kernel::Rng rng = kernel::make_stream(12, 0, 0);
  std::normal_distribution<double> normal;
  const Eigen::Index nu = sc.model.plant.nu(), n = sc.model.plant.n();
  std::vector<Eigen::VectorXd> us, drives;
  for (int k = 0; k < kPeriods; ++k) {
    us.emplace_back(nu);
    drives.emplace_back(n);
    for (Eigen::Index i = 0; i < nu; ++i) us.back()(i) = normal(rng);
    for (Eigen::Index i = 0; i < n; ++i) drives.back()(i) = 0.1 * normal(rng);
  }
  for (const auto& entry : sc.estimators) {
    auto est = entry.design->instantiate();
    double sink = 0.0;
    long allocations = 0;
    for (int k = 0; k < kPeriods; ++k) {
      g_allocations = 0;
      g_counting = k >= kWarmup;
      for (const auto& p : arrivals[static_cast<std::size_t>(k)]) est->on_packet(p, k);
      est->on_period(k, est::PeriodInput{us[static_cast<std::size_t>(k)],
                                         drives[static_cast<std::size_t>(k)]});
      sink += est->state()(0);
      if (const auto* x = est->extended()) sink += (*x)(0);
      if (const auto* P = est->covariance()) sink += (*P)(0, 0);
      if (const auto m = est->mode()) sink += *m;
      if (const auto* c = est->counters()) sink += c->flops;
      g_counting = false;
      allocations += g_allocations;
    }
    EXPECT_EQ(allocations, 0) << entry.name << " (" << what << "): heap allocations in "
                              << kPeriods - kWarmup << " periods after warm-up";
    EXPECT_TRUE(std::isfinite(sink) || est->status() != "ok") << entry.name;
  }
}

std::vector<std::string> all_estimators() {
  std::vector<std::string> v;
  for (const auto& e : estimator_registry().entries()) v.push_back(e.name);
  return v;
}

void* volatile g_keep = nullptr;  // keeps the allocations below from being optimised away

TEST(Allocation, TheCounterSeesOperatorNewAndEigen) {
  g_allocations = 0;
  g_counting = true;
  auto* v = new std::vector<int>(3);
  g_keep = v->data();
  Eigen::VectorXd x(17);
  g_keep = x.data();
  g_counting = false;
  EXPECT_EQ(g_allocations, 3) << "the vector object, its storage and Eigen's malloc";
  delete v;
}

TEST(Allocation, NoEstimatorAllocatesPerPeriodAfterWarmUp) {
  for (const auto& link : link_registry().entries()) {
    if (exercised_elsewhere(link.name)) continue;
    TempDir dir;
    const auto file =
        write_scenario(dir, scenario_text("lti", "white", link.name, all_estimators()));
    expect_no_allocation(*testing::load_one(file), "link " + link.name);
  }
}

TEST(Allocation, NoEstimatorAllocatesWithBufferedSensors) {
  // Two samples per packet (buffer = 1) for the kinds that accept buffered sensors.
  std::vector<std::string> kinds;
  for (const auto& k : all_estimators()) {
    if (!is_mode_kind(k)) kinds.push_back(k);
  }
  TempDir dir;
  std::string text = scenario_text("lti", "white", "delay", kinds);
  for (std::size_t p = 0; (p = text.find("link = \"net\"\n\n", p)) != std::string::npos; p += 20) {
    text.replace(p, 14, "link = \"net\"\nbuffer = 1\n\n");
  }
  expect_no_allocation(*testing::load_one(write_scenario(dir, text)), "buffered sensors");
}

TEST(Allocation, ModeEstimatorsOnAJumpLinearPlantDoNotAllocate) {
  TempDir dir;
  std::string text = scenario_text("jump_linear", "white", "bernoulli", {"imm", "mode_ss"});
  text.replace(text.find("[[actuator]]"),
               std::string("[[actuator]]\nlink = \"net\"\non_loss = \"hold\"\n\n").size(), "");
  expect_no_allocation(*testing::load_one(write_scenario(dir, text)), "jump_linear plant");
}

// The run itself (plant process, sensors and their policies, links, controller, actuation,
// recorder; open_loop as the only estimator): a run of 2P periods makes as many allocations as
// one of P periods, up to the pools that grow to their steady size (events, packets in flight).
// An allocation per period would add P.
long run_allocations(Scenario& sc, std::int64_t periods) {
  sc.run.periods = periods;
  g_allocations = 0;
  g_counting = true;
  simulate_run(sc, 0);
  g_counting = false;
  return g_allocations;
}

TEST(Allocation, ARunAllocatesNothingPerPeriod) {
  constexpr std::int64_t kPeriods = 4000;
  constexpr long kPoolGrowth = 16;  // a pool doubling a few more times in the longer run
  TempDir dir;
  for (const auto& p : plant_registry().entries()) {
    if (needs_sumo(p.name)) continue;
    for (const auto& in : input_registry().entries()) {
      for (const std::string policy : {"", "policy = \"send_on_delta\"\ndelta = 0.05\n"}) {
        std::string text = scenario_text(p.name, in.name, "delay", {"open_loop"});
        for (std::size_t at = text.find("[[sensor]]\n"); at != std::string::npos;
             at = text.find("[[sensor]]\n", at + 1)) {
          text.insert(at + 11, policy);
        }
        auto sc = testing::load_one(write_scenario(dir, text));
        const long once = run_allocations(*sc, kPeriods);
        const long twice = run_allocations(*sc, 2 * kPeriods);
        EXPECT_LE(twice - once, kPoolGrowth)
            << p.name << " plant, " << in.name << " input"
            << (policy.empty() ? "" : ", send-on-delta sensors") << ": " << once
            << " allocations in " << kPeriods << " periods, " << twice << " in " << 2 * kPeriods;
      }
    }
  }
}

}  // namespace
}  // namespace ncosim::sim
