// lmi/limits.h — resource limits of an LMI solve (see lmi/lmi.h).
#pragma once

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

class ResourceLimitError : public std::runtime_error {
 public:
  ResourceLimitError(const std::string& what, double estimated_bytes, double estimated_flops, int scalar_variables,
                     int largest)
      : std::runtime_error(what),
        bytes(estimated_bytes),
        flops(estimated_flops),
        variables(scalar_variables),
        largest_block(largest) {}
  double bytes, flops;  // the estimate
  int variables, largest_block;
};

}  // namespace ncosim::lmi
