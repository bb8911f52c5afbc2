// sim/registries.h — the registries of every component kind, filled once with the built-ins.
#pragma once

#include "estimators/estimator.h"
#include "models/input.h"
#include "models/link_factory.h"
#include "models/plant.h"
#include "sim/scenario.h"

namespace ncosim::sim {

const models::PlantRegistry& plant_registry();
const models::LinkRegistry& link_registry();
const models::InputRegistry& input_registry();
const est::EstimatorRegistry& estimator_registry();

// The [sumo] table's reader: ScenarioError when this build has no SUMO (NCOSIM_SUMO=OFF).
std::shared_ptr<MobilitySource> make_mobility(const Table& t, const RunSettings& run, const std::string& dir);
// True when built with the SUMO component.
bool have_sumo();

}  // namespace ncosim::sim
