// estimators/jump_observer.h — read access to a designed jump observer (its delay-extended
// model, its gain table and selection, its initial estimate), for tools that need more than
// the EstimatorDesign interface: the embedded C export (estimators/export_c.h).
#pragma once

#include "estimators/design/jump_design.h"
#include "estimators/estimator.h"
#include "estimators/extended_model.h"

namespace ncosim::est {

class JumpDesignAccess {
 public:
  virtual ~JumpDesignAccess() = default;
  virtual const ExtendedModel& extended_model() const = 0;
  virtual const JumpDesign& jump_design() const = 0;
  virtual const InitialEstimate& initial_estimate() const = 0;
};

}  // namespace ncosim::est
