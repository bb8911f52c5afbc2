// kinds.h — the registration functions of this example's kinds (one per file).
#pragma once

#include "estimators/estimator.h"
#include "models/link_factory.h"
#include "models/plant.h"
#include "models/send_policy.h"

void register_alpha_beta(ncosim::est::EstimatorRegistry& registry);
void register_mass_spring_damper(ncosim::models::PlantRegistry& registry);
void register_periodic_outage(ncosim::models::LinkRegistry& registry);
void register_deadband_heartbeat(ncosim::models::SendPolicyRegistry& registry);
