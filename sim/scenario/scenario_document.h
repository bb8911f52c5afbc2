// sim/scenario/scenario_document.h — a scenario's text as the TOML document its cases are built
// from (defined in sim/scenario/scenario.cc; `ncosim ladder` writes its scenarios from it too).
#pragma once

#include <toml++/toml.h>

#include <string>
#include <vector>

#include "sim/scenario/scenario_types.h"

namespace ncosim::sim {

// `text` parsed as `file`, every --set in `sets` applied, then [run] runs, periods and seed
// where `overrides` gives them (> 0, or set). Throws ScenarioError (FILE:LINE) on a syntax
// error or a bad --set. toml++ copies drop the source lines that error messages need, so a
// caller that needs a document per sweep case parses afresh.
toml::table parse_document(const std::string& text, const std::string& file,
                           const std::vector<std::string>& sets, const RunOverrides& overrides);

}  // namespace ncosim::sim
