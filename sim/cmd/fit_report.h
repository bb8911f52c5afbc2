// sim/cmd/fit_report.h — what `ncosim fit` (and `ncosim ladder`) make of the fitted families
// (models/fit.h): the short printed summary, fit.json (everything), fit.csv (one row per item)
// and link.toml (the selected family's [[link]], the others commented out). Columns and fields:
// results/README.md, "fit.csv, fit.json and link.toml".
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "models/fit.h"

namespace ncosim::sim {

// The fits of one trace, as every output names them.
struct FitSet {
  std::string trace;  // the trace file (or what it stands for)
  std::vector<models::FitResult> fits;
  std::vector<std::string> skipped;  // "FAMILY: why", families that could not be fitted
  std::size_t packets = 0, lost = 0;
  int longest_delay = -1;  // -1: nothing delivered
  std::string criterion = "bic";
  std::size_t best = 0;  // models::best_fit
  double seconds = 0.0;
};

// The summary: the trace, one line per family (log-likelihood, k, AIC, BIC, EM iterations,
// converged, goodness of fit), the selected family's parameters a user reads with their 95 %
// intervals (long delay laws summarised), and the [[link]] table when short. `verbose`: every
// family's every parameter.
std::string fit_summary(const FitSet& s, bool verbose);

std::string fit_json(const FitSet& s);
std::string fit_csv(const FitSet& s);
std::string fit_link_toml(const FitSet& s);

}  // namespace ncosim::sim
