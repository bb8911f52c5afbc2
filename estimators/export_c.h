// estimators/export_c.h — embedded C99 export of designed jump observers
// (`ncosim design FILE --export-c DIR`): per estimator a header and a source with the gain
// table, the gain selection (N counter and availability pattern -> gain index under S1..S4,
// as JumpObserver selects) and an allocation-free update on a caller-provided state struct.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "estimators/jump_observer.h"

namespace ncosim::est {

// A valid C identifier from an estimator name: every run of characters outside [A-Za-z0-9]
// becomes one '_', leading/trailing '_' dropped, lower case; "jump" when nothing is left;
// "jump_" prepended to a leading digit; '_' appended to a C keyword. Unique among `taken`
// (then "_2", "_3", ... appended); the result is added to `taken`.
std::string c_identifier(const std::string& name, std::vector<std::string>& taken);

struct CExportItem {
  std::string name;    // estimator name (for the comments)
  std::string prefix;  // c_identifier() of it: file and symbol prefix
  const JumpDesignAccess* jump = nullptr;
  const models::LinearPlant* plant = nullptr;
  double period = 1.0;  // seconds
  std::string origin;   // scenario file and sweep case, for the comments
};

// {file name, content} pairs: <prefix>.h and <prefix>.c for every item.
// Throws std::invalid_argument for a failed design (nothing to export).
std::vector<std::pair<std::string, std::string>> export_c(const std::vector<CExportItem>& items,
                                                          const std::string& generator);

}  // namespace ncosim::est
