// sim/cmd/list_keys.h — `ncosim list --keys [KIND] [--format md]`: every declared key of a kind (or
// of every kind) with type, unit, default, range or values and help (config/keys.h). The
// Markdown form is what scripts/gen_key_docs.py writes into scenarios/README.md between
// `<!-- keys:REGISTRY.KIND -->` and `<!-- /keys -->`.
#pragma once

#include <string>
#include <vector>

#include "config/keys.h"

namespace ncosim::sim {

// One registered kind, or one of the scenario's own sections ("section.run").
struct ListedKeys {
  std::string name;  // "link.bernoulli"
  std::string kind;  // "bernoulli"
  std::string help;
  const config::Keys* keys;
};
// Every registered kind of every registry, then the scenario's sections.
std::vector<ListedKeys> all_kinds();

// KIND: "link.bernoulli" (registry prefix: plant, link, input, estimator, send_policy) or a bare
// kind name (every registry's kind of that name); "" lists every kind. Exit status 2 with a
// did-you-mean on stderr when nothing matches.
int cmd_list_keys(const std::string& kind, bool markdown);

// The fit families of `ncosim fit` (models/fit_families.cc), for `ncosim list`.
void list_fit_families();

}  // namespace ncosim::sim
