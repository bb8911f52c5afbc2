// sim/scenario/extensions.h — kinds added from outside the tree (docs/extending.md): a program
// built on the installed package registers its plants, links, inputs, estimators, send policies
// and network kinds with one call in its own main, then runs the ncosim command line
// (sim/cmd/cli.h) as usual.
#pragma once

#include <functional>

#include "estimators/estimator.h"
#include "models/input.h"
#include "models/link_factory.h"
#include "models/plant.h"
#include "models/send_policy.h"
#include "network/backend.h"

namespace ncosim::sim {

// The registries an extension may add kinds to.
struct Registries {
  models::PlantRegistry& plants;
  models::LinkRegistry& links;
  models::InputRegistry& inputs;
  est::EstimatorRegistry& estimators;
  models::SendPolicyRegistry& send_policies;  // [[sensor]] policy
  network::NetworkRegistry& networks;         // [[network]] kind (network/backend.h)
};
using Extension = std::function<void(Registries&)>;

// `extension` runs once, after the built-in kinds are registered, when a registry is first used
// (sim/scenario/registries.h). Call it before anything reads a scenario; afterwards it throws
// std::logic_error. A kind whose name is already registered makes that first use throw
// std::logic_error.
void add_extension(Extension extension);

// `extension` runs now, on the registries as they are (built first if they were not): kinds added
// while a program runs (the Python module's estimators, python/). A name already registered throws
// std::logic_error and changes nothing. Never call it while another thread reads a scenario or
// holds a registry entry.
void add_extension_now(const Extension& extension);

}  // namespace ncosim::sim
