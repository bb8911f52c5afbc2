// sim/scenario/scenario_sections.h — the readers of a scenario's sections, one per top-level table,
// called by build_scenario() in this order (a reader may use what the earlier ones filled in:
// sensors name links, the input names estimators). Each reads and range-checks its own keys and
// throws ScenarioError (FILE:LINE: key 'PATH': ...) on bad input. What a component needs beyond
// its table is asked of the component, never of its kind name: a plant whose true state is a
// mobility vehicle says so (models::LinearPlant::vehicle_key), a link that can carry only so
// many packets says how many (models::Link::packet_bound).
#pragma once

#include <optional>
#include <string>

#include "config/config.h"
#include "config/run_settings.h"
#include "sim/scenario/registries.h"
#include "sim/scenario/scenario_types.h"

namespace ncosim::sim {

// [run]: horizon, warm-up, runs, seed, period, re-centring (defaults without the table).
config::RunSettings read_run(const config::Table& root);

// [plant] (required): the model of its kind, its disturbance, and the vehicle of the mobility
// source when the plant's true state is one. Returns what drives the state size, for the
// resource messages (sim/scenario/resource_limits.h). Needs sc.run and sc.mobility. `kinds`: the
// plant kinds (every registered one; a test passes its own).
std::string read_plant(const config::Table& root, const toml::table& doc, Scenario& sc,
                       const models::PlantRegistry& kinds = plant_registry());

// [[link]]: one link of its kind per table, unique names; relative paths from `dir`. Needs
// sc.run and sc.mobility.
// [[network]] and [[background]] (before the links, which name them; read by the network layer,
// network/networks.h) and, once the sensors are read, the check that a sensor sends over each
// network.
void read_networks(const config::Table& root, Scenario& sc);
// A vehicle whose node on a network is a link's or the sink has no background node there too
// ([[background]] vehicles = "all" names every vehicle).
void drop_doubled_riders(Scenario& sc);
void check_networks(const config::Table& root, const Scenario& sc);
void read_links(const config::Table& root, const std::string& dir, Scenario& sc,
                const models::LinkRegistry& kinds = link_registry());

// [[sensor]] (at least one): each on its link (by name), unique names; then every bounded link
// (a trace) must carry all the packets its sensors send in one run.
void read_sensors(const config::Table& root, Scenario& sc);

// [[actuator]]: none, or one per input channel in input order, each on its link.
void read_actuators(const config::Table& root, Scenario& sc);

// [input]: the input or controller of its kind (default none) and the actuation delay. Returns
// the table (or nothing) for bind_feedback_source().
std::optional<config::Table> read_input(const config::Table& root, Scenario& sc);

// [[estimator]] (at least one): each designed for sc.model after its resource estimate, unique
// names. `state_driver` is read_plant()'s result.
void read_estimators(const config::Table& root, const toml::table& doc,
                     const std::string& state_driver, Scenario& sc);

// The estimator that a state-feedback input or a controller reads (input.source /
// input.feedback), by name: sc.input.source_index.
void bind_feedback_source(const std::optional<config::Table>& input, Scenario& sc);

// run.recentre resolved against the plant, the input and the sensors: sc.recentre.
void choose_recentre(const config::Table& root, Scenario& sc);

// Reads [paired] (absent: defaults). Call after the estimators are read: an unknown
// `reference` name is reported at its line with the valid names.
PairedSettings read_paired(const config::Table& root, const toml::table& doc, const Scenario& sc);

}  // namespace ncosim::sim
