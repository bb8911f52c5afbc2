// sim/cmd/list_keys.cc — the declared keys of every registered kind, as text or Markdown.
#include "sim/cmd/list_keys.h"

#include <fmt/format.h>

#include <iostream>
#include <vector>

#include "config/keys.h"
#include "models/fit.h"
#include "sim/scenario/registries.h"
#include "sim/scenario/scenario_keys.h"

namespace ncosim::sim {

namespace {

template <class R>
void collect(const char* prefix, const R& registry, std::vector<ListedKeys>& out) {
  for (const auto& e : registry.entries())
    out.push_back({fmt::format("{}.{}", prefix, e.name), e.name, e.help, &e.keys});
}

void print(const ListedKeys& k, bool markdown) {
  if (markdown) {
    if (k.keys->empty()) {
      std::cout << "No keys of its own.\n";
      return;
    }
    std::cout << config::format_keys(*k.keys, true);
    return;
  }
  std::cout << fmt::format("{}: {}\n", k.name, k.help);
  std::cout << (k.keys->empty() ? "  (no keys of its own)\n" : config::format_keys(*k.keys, false));
}

}  // namespace

std::vector<ListedKeys> all_kinds() {
  std::vector<ListedKeys> out;
  collect("plant", plant_registry(), out);
  collect("link", link_registry(), out);
  collect("input", input_registry(), out);
  collect("estimator", estimator_registry(), out);
  collect("send_policy", send_policy_registry(), out);
  collect("network", network_registry(), out);
  // The scenario's own sections ("section.run", ...): their keys beside a kind's.
  for (const auto& k : section_keys()) {
    const std::string key = k.name.substr(k.name.find('.') + 1);
    std::string help = "the scenario's own keys";
    for (const auto& s : scenario_sections()) {
      if (s.key == key) help = s.help;
    }
    out.push_back({k.name, key, help, k.keys});
  }
  return out;
}

int cmd_list_keys(const std::string& kind, bool markdown) {
  const std::vector<ListedKeys> all = all_kinds();
  std::vector<const ListedKeys*> chosen;
  for (const auto& k : all) {
    if (kind.empty() || k.name == kind || k.kind == kind) chosen.push_back(&k);
  }
  if (chosen.empty()) {
    std::vector<std::string> names;
    for (const auto& k : all) names.push_back(k.name);
    const std::string hint = config::did_you_mean(kind, names);
    std::cerr << fmt::format(
        "ncosim: expected a kind (e.g. link.bernoulli; `ncosim list` lists "
        "them), got '{}'{}\n",
        config::escape_text(kind), hint.empty() ? "" : fmt::format(" (did you mean '{}'?)", hint));
    return 2;
  }
  for (std::size_t i = 0; i < chosen.size(); ++i) {
    if (i > 0) std::cout << "\n";
    if (markdown && chosen.size() > 1) std::cout << fmt::format("### {}\n\n", chosen[i]->name);
    print(*chosen[i], markdown);
  }
  return 0;
}

void list_fit_families() {
  std::cout << "fit families (ncosim fit --family):\n";
  for (const auto& f : models::fit_families())
    std::cout << fmt::format("  {:<18} {} (writes a [[link]] of kind {})\n", f.name, f.help,
                             f.link_kind);
}

}  // namespace ncosim::sim
