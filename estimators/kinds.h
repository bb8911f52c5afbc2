// estimators/kinds.h — registration functions of the built-in estimator kinds (one per file).
#pragma once

#include "estimators/estimator.h"

namespace ncosim::est {

void register_jump(EstimatorRegistry& registry);             // estimators/jump_observer.cc
void register_kalman_extended(EstimatorRegistry& registry);  // estimators/kalman_extended.cc
void register_kalman_buffer(EstimatorRegistry& registry);    // estimators/kalman_buffer.cc
void register_static_buffer(EstimatorRegistry& registry);    // estimators/static_buffer.cc
void register_open_loop(EstimatorRegistry& registry);        // estimators/open_loop.cc
void register_imm(EstimatorRegistry& registry);              // estimators/imm.cc
void register_mode_io(EstimatorRegistry& registry);          // estimators/mode_io.cc
void register_mode_ss(EstimatorRegistry& registry);          // estimators/mode_ss.cc
void register_sod_kalman(EstimatorRegistry& registry);       // estimators/sod_kalman.cc
void register_sod_jump(EstimatorRegistry& registry);         // estimators/sod_jump.cc

}  // namespace ncosim::est
