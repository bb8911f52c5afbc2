// models/link_factory.h — readers of [[link]] tables, one per registered link kind.
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "config/registry.h"
#include "models/link.h"
#include "models/mobility.h"

namespace ncosim::models {

struct LinkContext {
  std::string scenario_dir;                  // relative trace paths are resolved from here
  double period = 1.0;                       // the control period (s)
  std::shared_ptr<MobilitySource> mobility;  // the [sumo] mobility, null without it
  std::vector<std::string> networks;         // the names of the [[network]] tables, in order
  // Called by the trace kind with its largest delay, the trace's file and the line of the first
  // row holding it, and `named_by` ("FILE:LINE: key 'link[0].file'"); throws when the runs
  // cannot hold it (the scenario reader checks it against the resource limits,
  // sim/scenario/resource_limits.h).
  std::function<void(const std::string& trace, int line, std::int64_t delay,
                     const std::string& named_by)>
      check_trace_delay;
};

using LinkRegistry = config::Registry<std::unique_ptr<Link>, const LinkContext&>;
void register_links(LinkRegistry& registry);

}  // namespace ncosim::models
