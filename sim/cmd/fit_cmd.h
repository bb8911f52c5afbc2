// sim/cmd/fit_cmd.h — `ncosim fit TRACE`: channel models fitted to a packet trace (models/fit.h),
// a [[link]] table ready to paste and a diagnostics CSV.
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
  std::string name;  // [[link]] name (default: the trace's stem)
};

// Exit status: 0, or 2 for bad input (nothing written). Throws ScenarioError for bad input.
int cmd_fit(const FitArgs& args);

}  // namespace ncosim::sim
