// sumo/sumo.h — the SUMO component's entry points for the rest of ncosim (registry.cc, cli.cc).
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "config/run_settings.h"
#include "models/link_factory.h"
#include "models/mobility.h"
#include "models/plant.h"

namespace ncosim::sumo {

// `sumo_distance` link and `sumo_vehicle` plant.
void register_links(models::LinkRegistry& registry);
void register_plants(models::PlantRegistry& registry);
// The [sumo] table read (files checked); recording happens in MobilitySource::prepare().
std::shared_ptr<models::MobilitySource> make_mobility(const config::Table& t,
                                                      const config::RunSettings& run,
                                                      const std::string& dir);
// A kind whose table names vehicles of the [sumo] mobility (models::MobilitySource::vehicle)
// declares those keys when it registers, so that they are known before its table is read: the
// [plant] kind or a [[link]] kind `kind`, naming vehicles under the table keys `keys`.
// kNetwork: a [[network]] table of any kind (`kind` "").
enum class VehicleTable { kPlant, kLink, kNetwork };
void declare_vehicle_keys(VehicleTable table, std::string kind, std::vector<std::string> keys);

// Before the cases of a scenario are built: the vehicles that case document `doc` will read (the
// values of the declared vehicle keys of its [plant] and [[link]] tables) are noted under its
// traffic key, so that the first case's prepare() records them all in one SUMO run per
// realisation and every later case (a sweep over receivers, presets, ...) reuses that recording.
// A bad [sumo] table (ScenarioError) is ignored here: the case's own build reports it.
void announce_vehicles(const toml::table& doc, const std::string& file, const std::string& dir);

// `ncosim channel PRESET [--csv] [--gnuplot] [--max-distance M] [--step S]`.
int channel_command(const std::string& preset, bool csv, bool gnuplot, double max_distance,
                    double step);

}  // namespace ncosim::sumo
