// sim/cmd/fit_cmd.h — `ncosim fit TRACE`: channel models fitted to a packet trace (models/fit.h),
// a short summary on stdout (sim/cmd/fit_report.h), a [[link]] table ready to paste (link.toml),
// every family's every estimate and interval (fit.json) and a diagnostics CSV (fit.csv).
#pragma once

#include <string>
#include <vector>

namespace ncosim::sim {

struct FitArgs {
  std::string trace;
  std::string out;                    // default: results/fit_<trace stem>
  std::vector<std::string> families;  // default: every family
  std::string criterion = "bic";
  int starts = 4;
  int max_iterations = 2000;  // EM iterations per hidden family (models::FitOptions)
  bool verbose = false;       // print every family's every parameter
  std::string name;           // [[link]] name (default: the trace's stem)
};

// Exit status: 0, or 2 for bad input (nothing written). Throws ScenarioError for bad input.
int cmd_fit(const FitArgs& args);

}  // namespace ncosim::sim
