// lmi/limits.cc — resource limits of an LMI solve: the estimate of its memory and work, and
// the refusal beyond the limits (see lmi/limits.h).
#include "lmi/limits.h"

#include <sys/resource.h>

#include <algorithm>
#include <cstdio>
#include <functional>
#include <mutex>
#include <string>

#include "lmi/problem_impl.h"

namespace ncosim::lmi {

namespace {
std::mutex& limits_mutex() {
  static std::mutex m;
  return m;
}
ResourceLimits& limits_storage() {
  static ResourceLimits l;
  return l;
}
std::string human(double bytes) {
  char buf[64];
  if (bytes >= 1e9)
    std::snprintf(buf, sizeof buf, "%.1f GB", bytes / 1e9);
  else
    std::snprintf(buf, sizeof buf, bytes >= 1e8 ? "%.0f MB" : "%.3g MB", bytes / 1e6);
  return buf;
}

// Whole GFLOP from 100 on, else three significant digits (a limit of 0.01 GFLOP is not "0").
std::string gflop(double flops) {
  char buf[64];
  std::snprintf(buf, sizeof buf, flops >= 1e11 ? "%.0f GFLOP" : "%.3g GFLOP", flops / 1e9);
  return buf;
}

thread_local std::function<void(const SolveEstimate&)> t_solve_observer;

// The process's address-space limit in bytes (RLIMIT_AS), 0 when unlimited.
double address_space_limit() {
  struct rlimit rl {};
  if (::getrlimit(RLIMIT_AS, &rl) != 0 || rl.rlim_cur == RLIM_INFINITY) return 0.0;
  return static_cast<double>(rl.rlim_cur);
}

}  // namespace

ScopedSolveObserver::ScopedSolveObserver(std::function<void(const SolveEstimate&)> observer)
    : previous_(std::move(t_solve_observer)) {
  t_solve_observer = std::move(observer);
}
ScopedSolveObserver::~ScopedSolveObserver() { t_solve_observer = std::move(previous_); }

void set_resource_limits(const ResourceLimits& limits) {
  std::lock_guard<std::mutex> g(limits_mutex());
  limits_storage() = limits;
}

ResourceLimits resource_limits() {
  std::lock_guard<std::mutex> g(limits_mutex());
  return limits_storage();
}

SolveEstimate Problem::Impl::estimate() const {
  const double k = nraw;
  // CSDP: the Schur complement O (k x k) and its factor, k-vectors, and about 11 copies of the
  // block-diagonal X (X, Z, dX, dZ, work matrices); the expanded coefficients.
  const double bytes = 16.0 * k * k + 11.0 * block_bytes + coef_bytes;
  // 50 iterations of: Schur complement k^2 * (largest block), Cholesky k^3 / 3, block work.
  const double flops =
      50.0 * (k * k * std::max(1, largest_block) + k * k * k / 3.0 + 10.0 * block_flops);
  return SolveEstimate{bytes, flops, nraw, largest_block};
}

void Problem::Impl::check_resources() const {
  const ResourceLimits lim = resource_limits();
  const SolveEstimate e = estimate();
  const double bytes = e.bytes, flops = e.flops;
  const bool over_memory = lim.memory_bytes > 0.0 && bytes > lim.memory_bytes;
  const bool over_work = lim.work_flops > 0.0 && flops > lim.work_flops;
  const double address_space = address_space_limit();
  if (!over_memory && address_space > 0.0 && bytes > address_space) {
    throw ResourceLimitError(
        "an LMI problem of " + std::to_string(nraw) + " scalar variables (largest block " +
            std::to_string(largest_block) + ") needs an estimated " + human(bytes) +
            ", above the process's address-space limit of " + human(address_space) +
            " (ulimit -v; the solver would end the process when its allocation fails)",
        bytes, flops, nraw, largest_block, true);
  }
  if (!over_memory && !over_work) return;
  std::string what =
      over_memory
          ? "an LMI problem of " + std::to_string(nraw) + " scalar variables (largest block " +
                std::to_string(largest_block) + ") needs an estimated " + human(bytes) +
                ", above the memory limit of " + human(lim.memory_bytes)
          : "an LMI problem of " + std::to_string(nraw) + " scalar variables (largest block " +
                std::to_string(largest_block) + ") needs an estimated " + gflop(flops) +
                ", above the work limit of " + gflop(lim.work_flops);
  throw ResourceLimitError(what, bytes, flops, nraw, largest_block);
}

void observe_solve(const Problem::Impl& p) {
  if (t_solve_observer) t_solve_observer(p.estimate());
}

}  // namespace ncosim::lmi
