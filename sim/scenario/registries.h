// sim/scenario/registries.h — the registries of every component kind, filled once with the
// built-ins.
#pragma once

#include <memory>
#include <string>

#include "config/config.h"
#include "config/run_settings.h"
#include "estimators/estimator.h"
#include "models/input.h"
#include "models/link_factory.h"
#include "models/mobility.h"
#include "models/plant.h"
#include "models/send_policy.h"
#include "network/backend.h"

namespace ncosim::sim {

const models::PlantRegistry& plant_registry();
const models::LinkRegistry& link_registry();
const models::InputRegistry& input_registry();
const est::EstimatorRegistry& estimator_registry();
const models::SendPolicyRegistry& send_policy_registry();
const network::NetworkRegistry& network_registry();

// The [sumo] table's reader: ScenarioError when this build has no SUMO (NCOSIM_SUMO=OFF).
std::shared_ptr<models::MobilitySource> make_mobility(const config::Table& t,
                                                      const config::RunSettings& run,
                                                      const std::string& dir);
// Called for every case document before the cases are built: lets the mobility source note what
// each case will read (sumo/: the vehicles, so that one recording serves every case).
void announce_mobility(const toml::table& case_doc, const std::string& file,
                       const std::string& dir);
// True when built with the SUMO component.
bool have_sumo();

}  // namespace ncosim::sim
