// estimators/sod_jump.h — the send-on-delta jump observer (the send-on-delta co-design paper,
// eq. (3), (7)): x^[t-] = A x^[t-1] + (known input), x^[t] = x^[t-] + L(alpha[t]) (m[t] - C
// x^[t-]), with m the held measurements and alpha[t] the sensors that sent at t; gains from the
// H-infinity LMI designs (estimators/design/sod_design.h). Its design also carries the threshold
// co-design parameters, run by `ncosim codesign` (sim/cmd/cli.cc).
#pragma once

#include <optional>

#include "estimators/design/sod_design.h"
#include "estimators/estimator.h"

namespace ncosim::est {

class SodJumpDesign : public EstimatorDesign {
 public:
  // The system, design settings and co-design settings as read from the table.
  virtual const sod::SodSystem& system() const = 0;
  virtual const sod::SodDesignSpec& spec() const = 0;
  virtual std::optional<sod::CodesignSpec> codesign_spec(double mu, double z0) const = 0;
  virtual double mu() const = 0;  // [codesign] mu (0 when absent)
};

}  // namespace ncosim::est
