// sim/analysis/run_folder.h — an output folder as `ncosim compare` reads it (manifest.json,
// runs.csv, summary.csv), and compare's bad-input error (sim/analysis/compare.h).
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "config/config.h"

namespace ncosim::sim {

// Bad input to compare (a ScenarioError: `ncosim` prints it and exits 2).
class CompareInputError : public config::ScenarioError {
 public:
  using config::ScenarioError::ScenarioError;
};

// One output folder as compare reads it.
struct RunFolder {
  std::string dir;
  std::string scenario, title, scenario_hash;
  std::uint64_t seed = 0;
  // manifest.json's `inputs`: every file the scenario read -> content hash (absent in folders of
  // older versions: then not compared).
  std::optional<std::map<std::string, std::string>> inputs;
  std::string partial;  // "K of N runs ..." when manifest.json says the campaign is not complete
  // manifest.json's top-level fields (strings bare, the rest as compact JSON), for what differs.
  std::map<std::string, std::string> fields;
  // The hash of the scenario text and --set (manifest's scenario_text_hash, else from the run
  // store's text); nullopt in a folder of an older ncosim without a readable store.
  std::optional<std::string> text_hash;
  std::optional<std::string> text;  // the scenario text the campaign ran (runs.sqlite), if readable
  std::vector<std::string> sweep_keys;
  struct Row {
    std::vector<std::string> labels;  // per sweep key
    std::string estimator;
    std::vector<std::int64_t> run;             // run indices, in file order
    std::vector<std::optional<double>> value;  // the metric, finite and >= 0 (nullopt: empty cell)
    std::vector<bool> diverged;
  };
  std::vector<Row> rows;  // in first-appearance order
  // Per row, from summary.csv (read_row_statuses; empty without it): the row's status and the
  // status its scenario expects ([[estimator]] expected_status; empty: "ok").
  struct RowStatus {
    std::string status, expected_status;
  };
  std::vector<RowStatus> statuses;
};

}  // namespace ncosim::sim
