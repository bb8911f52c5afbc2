// sim/cmd/codesign.h — `ncosim codesign`: the greedy threshold co-design (send-on-delta paper,
// section 4) for the sod_jump estimators of a scenario, and its codesign.json.
#pragma once

#include <nlohmann/json.hpp>
#include <ostream>
#include <string>

#include "sim/scenario/scenario.h"

namespace ncosim::sim {

struct CodesignOptions {
  std::string estimator;  // "" : every sod_jump estimator
  double mu = 0.0;        // 0: each estimator's [codesign] mu
  bool progress = false;  // one line per accepted step on stderr
};

// Runs z~0 and the greedy co-design; returns the codesign.json document. Throws ScenarioError
// when no estimator qualifies.
nlohmann::json run_codesign(const Scenario& sc, const CodesignOptions& options);

// What `ncosim codesign` prints of each estimator of codesign.json `j` (thresholds and bounds to
// six significant digits: codesign.json keeps them exact); returns whether every status is ok.
bool print_codesign(const nlohmann::json& j, std::ostream& os);

// "[0.009, 0.02]": numbers to six significant digits (0.009000000000000001 prints as 0.009).
std::string short_numbers(const nlohmann::json& array);

}  // namespace ncosim::sim
