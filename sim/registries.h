// sim/registries.h — the registries of every component kind, filled once with the built-ins.
#pragma once

#include "estimators/estimator.h"
#include "models/input.h"
#include "models/link_factory.h"
#include "models/plant.h"

namespace ncosim::sim {

const models::PlantRegistry& plant_registry();
const models::LinkRegistry& link_registry();
const models::InputRegistry& input_registry();
const est::EstimatorRegistry& estimator_registry();

}  // namespace ncosim::sim
