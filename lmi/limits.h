// lmi/limits.h — resource limits of an LMI solve (see lmi/lmi.h).
#pragma once

#include <functional>
#include <stdexcept>
#include <string>

namespace ncosim::lmi {

// Process-wide resource limits of one solve (0: none). Problem::add() and Problem::solve()
// estimate the memory of the expanded coefficients and of CSDP (the k x k Schur complement, the
// block matrices and their work copies) and the work of an interior-point solve (50 iterations of
// a Schur build and Cholesky factorisation) before anything large is allocated, and throw
// ResourceLimitError beyond them (CSDP itself would exit the process when malloc fails).
struct ResourceLimits {
  double memory_bytes = 0.0;
  double work_flops = 0.0;
};
void set_resource_limits(const ResourceLimits& limits);
ResourceLimits resource_limits();

// Thrown also when the memory estimate exceeds the process's address-space limit (`ulimit -v`,
// RLIMIT_AS), whatever the limits above: CSDP ends the process with exit(205) when its malloc
// fails, so a solve that cannot fit is refused before it starts (`address_space` is then true).
class ResourceLimitError : public std::runtime_error {
 public:
  ResourceLimitError(const std::string& what, double estimated_bytes, double estimated_flops,
                     int scalar_variables, int largest, bool over_address_space = false)
      : std::runtime_error(what),
        bytes(estimated_bytes),
        flops(estimated_flops),
        variables(scalar_variables),
        largest_block(largest),
        address_space(over_address_space) {}
  double bytes, flops;  // the estimate
  int variables, largest_block;
  bool address_space;
};

// Called on the solving thread before CSDP starts, with the solve's estimate (sim/ prints a note
// for large designs). One observer per thread, set for the scope of this object.
struct SolveEstimate {
  double bytes = 0.0, flops = 0.0;
  int variables = 0, largest_block = 0;
};
class ScopedSolveObserver {
 public:
  explicit ScopedSolveObserver(std::function<void(const SolveEstimate&)> observer);
  ~ScopedSolveObserver();
  ScopedSolveObserver(const ScopedSolveObserver&) = delete;
  ScopedSolveObserver& operator=(const ScopedSolveObserver&) = delete;

 private:
  std::function<void(const SolveEstimate&)> previous_;
};

}  // namespace ncosim::lmi
