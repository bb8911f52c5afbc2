// sim/cmd/find.h — `ncosim find`: the value of one scenario key at which a design quantity of an
// estimator reaches a target (e.g. the minimum delivery probability with predicted_mse <= 0.03,
// Dolz et al. 2014, Fig. 5), by a scan of [lo, hi] followed by a bisection. Designs only: no
// simulation. The quantity must be monotone in the key for the bisection to mean anything: the
// scan and every bisection point are checked and a violation is reported, never hidden.
#pragma once

#include <map>
#include <optional>
#include <ostream>
#include <string>
#include <vector>

#include "sim/scenario/scenario.h"

namespace ncosim::sim {

struct FindTarget {
  std::string quantity;  // a numeric field of the estimator's design.json entry
  std::string op;        // "<=", ">=", "<" or ">"
  double value = 0.0;
};

// Parses "QUANTITY<=VALUE" (also >=, <, >). Throws ScenarioError with `origin` on bad text.
FindTarget parse_target(const std::string& text, const std::string& origin);

struct FindOptions {
  std::string key;  // scenario key path, set as a float (e.g. link[0].delivery)
  FindTarget target;
  std::vector<std::string> estimators;  // empty: every estimator
  double lo = 0.0, hi = 1.0;
  double tol = 1e-4;  // bisection stops when the bracket is narrower
  int scan = 8;       // scan intervals before the bisection
};

struct FindRow {
  std::vector<std::string> sweep_labels;
  std::string estimator;
  std::optional<double> threshold;  // the bracket end that meets the target
  std::optional<double> other;      // the other bracket end (does not meet it)
  std::optional<double> value;      // the quantity at `threshold`
  int evaluations = 0;              // designs evaluated for this row (scan + bisection)
  bool monotone = true;             // every evaluated point monotone in the key
  int crossings = 0;                // changes of "target met" over the scan
  std::string status;               // ok | not_bracketed | several_crossings | not_monotone
};

struct FindResult {
  std::vector<SweepAxis> sweeps;
  std::vector<FindRow> rows;
};

// Runs the search for every sweep case and every selected estimator. Warnings go to `log`.
// Throws ScenarioError for bad input (unknown estimator, a key that does not load).
FindResult find_threshold(const std::string& file, const std::vector<std::string>& sets,
                          const FindOptions& opt, std::ostream& log);

std::string find_csv(const FindResult& result, const FindOptions& opt);

// True when the finite values, ordered by key, never go both up and down (1e-9 relative
// slack); points without a value (failed designs) are skipped.
bool is_monotone(const std::map<double, std::optional<double>>& points);

// A double as a TOML float literal that reads back exactly ("0.5", "1.0", "1e-05").
std::string toml_float(double v);

}  // namespace ncosim::sim
