// estimators/imm.h — access to the `imm` estimator's IMM core (per-mode estimates, likelihoods)
// for tests and tools; the kind itself is registered by register_imm (estimators/kinds.h).
#pragma once

#include "estimators/estimator.h"
#include "estimators/imm_filter.h"

namespace ncosim::est {

// The IMM core of an `imm` estimator, or nullptr for any other kind.
const ImmFilter* imm_filter_of(const Estimator& estimator);

}  // namespace ncosim::est
