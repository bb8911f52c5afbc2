// sim/scenario/scenario_keys.h — the scenario format as data: the keys of the scenario's own
// sections ([run], the common keys of [plant], [[sensor]], [[link]], [input], [[estimator]], ...)
// declared like a kind's (config/keys.h), and every section with the registry whose kinds it
// selects. The section readers (sim/scenario/scenario_sections.cc) read through these declarations
// where the keys are theirs; `ncosim list --keys`, scenarios/README.md's generated tables and
// `ncosim schema` (sim/cmd/schema.h) are made from them.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "config/keys.h"

namespace ncosim::sim {

const config::Keys& top_level_keys();  // title and the sections
const config::Keys& run_keys();        // [run]
// run.warmup when absent: min(100, periods / 10) (run_keys() prints the same rule).
std::int64_t default_warmup(std::int64_t periods);
const config::Keys& plant_common_keys();      // [plant] beside its kind's keys
const config::Keys& sensor_common_keys();     // [[sensor]] beside its send policy's keys
const config::Keys& link_common_keys();       // [[link]] beside its kind's keys
const config::Keys& network_common_keys();    // [[network]] beside its kind's keys
const config::Keys& background_keys();        // [[background]]
const config::Keys& actuator_keys();          // [[actuator]]
const config::Keys& input_common_keys();      // [input] beside its kind's keys
const config::Keys& estimator_common_keys();  // [[estimator]] beside its kind's keys
const config::Keys& sweep_keys();             // [[sweep]]
const config::Keys& sumo_keys();              // [sumo] (read by sumo/ when built with SUMO)
const config::Keys& paired_keys();            // [paired]

// One kind of a section: a registry entry's name, help and keys.
struct SectionKind {
  std::string name;
  std::string help;
  const config::Keys* keys = nullptr;  // empty when the kind declares none
  bool declared = false;  // the kind declared its keys (config::Registry::Entry::declared)
};

// One top-level key of a scenario.
struct Section {
  std::string key;                     // "run", "estimator"
  bool array = false;                  // [[key]]
  bool required = false;               // the scenario must have it
  std::string help;                    // one line
  const config::Keys* keys = nullptr;  // the section's own keys (nullptr: not declared here)
  std::string kind_key;                // "kind", "policy": selects one of `kinds` ("" when none)
  std::string default_kind;            // the kind when kind_key is absent ("" = required)
  std::vector<SectionKind> kinds;
  bool closed = true;  // the reader rejects keys that are not declared (Table::finish)
};

// "expected a [plant] table (required: the plant model), got none", "expected at least one
// [[sensor]] table, got none": a required section that is absent (or an empty array).
std::string missing_section_message(const Section& section);

// Every top-level section, in the order of top_level_keys(), with the registered kinds.
std::vector<Section> scenario_sections();

// "section.run", "section.estimator", ...: the names under which `ncosim list --keys` and the
// generated docs know the sections' own keys, with their keys.
struct NamedKeys {
  std::string name;
  const config::Keys* keys;
};
std::vector<NamedKeys> section_keys();

}  // namespace ncosim::sim
