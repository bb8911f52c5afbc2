// sim/scenario/scenario_types.cc — see sim/scenario/scenario_types.h.
#include "sim/scenario/scenario_types.h"

namespace ncosim::sim {

const std::vector<std::string>& expected_status_values() {
  // The order of results/README.md `### status`.
  static const std::vector<std::string> values{
      "ok",         "diverged",      "precision_lost",   "numerical_failure",
      "heavy_tail", "design_failed", "ci_target_not_met"};
  return values;
}

bool status_as_expected(const std::string& status, const std::string& expected) {
  if (expected.empty()) return status == "ok";
  // A failed design's status carries the design's own words (design_unstable: p0 ...).
  if (expected == "design_failed") return status.rfind("design_", 0) == 0;
  return status == expected;
}

}  // namespace ncosim::sim
