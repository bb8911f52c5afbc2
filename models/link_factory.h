// models/link_factory.h — readers of [[link]] tables, one per registered link kind.
#pragma once

#include <memory>
#include <string>

#include "config/mobility.h"
#include "config/registry.h"
#include "models/link.h"

namespace ncosim::models {

struct LinkContext {
  std::string scenario_dir;  // relative trace paths are resolved from here
  double period = 1.0;       // the control period (s)
  std::shared_ptr<sim::MobilitySource> mobility;  // the [sumo] mobility, null without it
};

using LinkRegistry = sim::Registry<std::unique_ptr<Link>, const LinkContext&>;
void register_links(LinkRegistry& registry);

}  // namespace ncosim::models
