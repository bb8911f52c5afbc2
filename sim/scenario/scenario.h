// sim/scenario/scenario.h — a scenario file parsed, validated and designed: everything a campaign
// needs. load_cases() reads the TOML file, applies --set overrides, expands [[sweep]] tables into
// cases and builds every case (estimator designs included) before anything runs, so bad
// input is reported (ScenarioError) before t = 0 and nothing is written.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "config/config.h"
#include "config/input_files.h"
#include "config/mobility.h"
#include "config/run_settings.h"
#include "config/toml_path.h"
#include "estimators/estimator.h"
#include "models/input.h"
#include "models/link.h"
#include "models/plant.h"
#include "sim/analysis/paired.h"

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

struct Scenario {
  std::string file;
  std::string title;
  RunSettings run;
  std::string plant_kind;
  est::Model model;  // plant, sensors (with pointers into links)
  models::InputSpec input;
  models::Disturbance disturbance;  // deterministic part of w ([plant.disturbance])
  std::vector<LinkEntry> links;
  std::vector<EstimatorEntry> estimators;
  bool recentre = false;  // simulate in re-centred coordinates (see scenarios/README.md)
  // [sumo]: the mobility source (null without it) and the vehicle whose longitudinal motion is
  // the true plant state (-1: the plant is simulated from its model).
  std::shared_ptr<MobilitySource> mobility;
  int plant_vehicle = -1;
  PairedSettings paired;  // [paired]: the reference of the paired columns (sim/analysis/paired.h)
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
  InputFiles inputs;
};

// Command-line overrides applied to [run] after --set (0 / empty: keep the file's).
struct RunOverrides {
  std::int64_t runs = 0;
  std::int64_t periods = 0;
  std::optional<std::uint64_t> seed;
};

// `only_case` (0-based index in sweep order): build that case only; `cases` then holds it
// alone and `sweeps` still lists every axis (used by `ncosim find`, which redesigns one case
// at many values of a key).
LoadedScenario load_cases(const std::string& file, const std::vector<std::string>& sets,
                          const RunOverrides& overrides = {},
                          std::optional<std::size_t> only_case = std::nullopt);

// The same from the scenario's text (e.g. kept in a run store); `file` names it in messages
// and its folder resolves relative paths.
LoadedScenario load_cases_text(const std::string& file, const std::string& text,
                               const std::vector<std::string>& sets,
                               const RunOverrides& overrides = {},
                               std::optional<std::size_t> only_case = std::nullopt);

// Parses and validates one scenario table (no sweep expansion).
std::unique_ptr<Scenario> build_scenario(const toml::table& doc, const std::string& file,
                                         const std::string& dir);

std::string fnv1a_hex(const std::string& text);

// FNV-1a 64 (hex) of a scenario's text followed by "\n--set A" for each --set assignment: what
// the campaign simulates, without the --runs/--periods/--seed that `hash` also covers (so two
// campaigns of one scenario with other runs or seeds share it; `ncosim compare` reads it from
// manifest.json's scenario_text_hash). `hash` hashes the same input followed by "\n--runs N",
// "\n--periods N", "\n--seed N" for those given.
std::string scenario_text_hash(const std::string& text, const std::vector<std::string>& sets);

}  // namespace ncosim::sim
