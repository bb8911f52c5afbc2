// sim/scenario/scenario.h — a scenario file parsed, validated and designed: everything a campaign
// needs. load_cases() reads the TOML file, applies --set overrides, expands [[sweep]] tables into
// cases and builds every case (estimator designs included) before anything runs, so bad
// input is reported (ScenarioError) before t = 0 and nothing is written.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "sim/scenario/scenario_types.h"

namespace ncosim::sim {

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

// While one is alive, load_cases(name, ...) reads `text` in place of the file `name` (every
// command: run, check, design, record-link...): how a program that embeds the command line runs
// a scenario it holds in memory (the Python module's dict or TOML string, python/). Relative
// paths in the text resolve from `name`'s folder (the working folder for "<dict>"). One at a
// time per name; not for use while another thread reads scenarios.
class ScenarioText {
 public:
  ScenarioText(std::string name, std::string text);
  ~ScenarioText();
  ScenarioText(const ScenarioText&) = delete;
  ScenarioText& operator=(const ScenarioText&) = delete;

 private:
  std::string name_;
};

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
