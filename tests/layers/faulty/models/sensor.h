// tests/layers/faulty/models/sensor.h — a models header with one fault.
#pragma once

#include <Eigen/Dense>

#include "config/config.h"
#include "estimators/estimator.h"  // fault: estimators are above the models
#include "kernel/rng.h"
