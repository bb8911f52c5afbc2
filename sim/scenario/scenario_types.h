// sim/scenario/scenario_types.h — what a scenario is made of once read: the scenario of one case
// (plant, sensors, links, estimators and their designs, run settings), the sweep axes and the
// loaded cases. The reader (sim/scenario/scenario.h) builds them; everything above uses them.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "config/config.h"
#include "config/input_files.h"
#include "config/run_settings.h"
#include "config/toml_path.h"
#include "estimators/estimator.h"
#include "models/input.h"
#include "models/link.h"
#include "models/mobility.h"
#include "models/plant.h"
#include "network/networks.h"

namespace ncosim::sim {

struct LinkEntry {
  std::string name;
  std::string kind;
  std::unique_ptr<models::Link> link;
};

struct EstimatorEntry {
  std::string name;
  std::string kind;
  // [[estimator]] expected_status: the row status the scenario expects ("" = not declared, i.e.
  // "ok"); `run --fail-on-status` and the tables treat only other statuses as a problem.
  std::string expected_status;
  std::unique_ptr<est::EstimatorDesign> design;
};

// The values [[estimator]] expected_status accepts: the row statuses of summary.csv
// (results/README.md `### status`), "design_failed" standing for every design_<status>.
const std::vector<std::string>& expected_status_values();
// Whether a row's `status` is the one its scenario expects (`expected` empty: "ok").
bool status_as_expected(const std::string& status, const std::string& expected);

// [paired] (read_paired, sim/scenario/scenario_sections.h; used by sim/analysis/paired.h).
struct PairedSettings {
  std::string reference;  // estimator name ("" : the default, see reference_estimator_index)
  int reference_line = 0;
  // [paired] reference_case: (sweep key path, value as the sweep label text), in file order.
  std::vector<std::pair<std::string, std::string>> reference_case;
  int reference_case_line = 0;
  std::string file;
};

struct Scenario {
  std::string file;
  std::string title;
  config::RunSettings run;
  std::string plant_kind;
  est::Model model;  // plant, sensors (with pointers into links)
  models::InputSpec input;
  models::Disturbance disturbance;  // deterministic part of w ([plant.disturbance])
  std::vector<LinkEntry> links;
  // [[network]], in order (the links name them), and their [[background]] nodes
  // (network/networks.h).
  network::Networks networks;
  std::vector<EstimatorEntry> estimators;
  bool recentre = false;  // simulate in re-centred coordinates (see scenarios/README.md)
  // [sumo]: the mobility source (null without it) and the vehicle whose longitudinal motion is
  // the true plant state (-1: the plant is simulated from its model).
  std::shared_ptr<models::MobilitySource> mobility;
  int plant_vehicle = -1;
  PairedSettings paired;  // [paired]: the reference of the paired columns (read_paired,
                          // sim/scenario/scenario_sections.h)
};

struct SweepAxis {
  std::string key;
  std::vector<std::string> labels;  // TOML text of each value
};

struct Case {
  std::vector<std::string> labels;  // one per sweep axis
  std::unique_ptr<Scenario> scenario;
};

struct LoadedScenario {
  std::string file;
  std::string text;  // the file's text
  std::string hash;  // FNV-1a 64 of the text, the --set and the --runs/--periods/--seed given, hex
  std::string
      text_hash;  // scenario_text_hash(text, overrides): the same without --runs/--periods/--seed
  std::vector<std::string> overrides;
  std::vector<SweepAxis> sweeps;
  std::vector<Case> cases;
  // Every external file the scenario read (trace, SUMO inputs, ...), path relative to the
  // scenario's folder -> content hash (config/input_files.h): part of a campaign's identity.
  config::InputFiles inputs;
};

// Command-line overrides applied to [run] after --set (0 / empty: keep the file's).
struct RunOverrides {
  std::int64_t runs = 0;
  std::int64_t periods = 0;
  std::optional<std::uint64_t> seed;
};

}  // namespace ncosim::sim
