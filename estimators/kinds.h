// estimators/kinds.h — registration functions of the built-in estimator kinds (one per file).
#pragma once

#include "estimators/estimator.h"

namespace ncosim::est {

void register_jump(EstimatorRegistry& registry);             // estimators/jump_observer.cc
void register_kalman_extended(EstimatorRegistry& registry);  // estimators/kalman_extended.cc
void register_open_loop(EstimatorRegistry& registry);        // estimators/open_loop.cc
void register_sod_kalman(EstimatorRegistry& registry);       // estimators/sod_kalman.cc
void register_sod_jump(EstimatorRegistry& registry);         // estimators/sod_jump.cc

}  // namespace ncosim::est
