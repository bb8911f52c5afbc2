// sim/scenario/scenario_check.h — every independent error of a scenario at once (issue 40 part 4).
//
// Before any component is built, one pass over the whole document checks every table of every
// section against the declared keys (sim/scenario/scenario_keys.h: the section's own keys and its
// kind's, config/key_check.h): unknown tables and keys (with a did-you-mean), unknown kinds, wrong
// types, values out of their declared range or not among their values, arrays with the wrong
// number of entries, required keys or sections missing. These errors are independent (each is
// shown by one value, read alone), so all of them are reported, in file order (the first
// config::ScenarioError::kMaxShown, then how many more). Only when there are none are the sections
// read and the components built; an error found then (a size against the plant, a covariance that
// is not PSD, a name that must exist elsewhere, a design that fails) is the first one only, since
// the later ones often follow from it (a wrong plant makes every sensor's size wrong).
//
// A kind registered without declaring its keys (an extension, a Python estimator) has its table's
// declared common keys checked; its own keys are its reader's (Table::finish). A table whose kind
// is unknown has only its common keys checked (its other keys cannot be judged).
#pragma once

#include <toml++/toml.h>

#include <string>
#include <vector>

namespace ncosim::sim {

// Every key-level error of `doc` (messages FILE:LINE: key 'PATH': ...), in file order. `swept`: the
// key paths that [[sweep]] tables set (a required value one of them provides is not missing; an
// error at a swept key's written value says that it must be valid too).
std::vector<std::string> scenario_key_errors(const toml::table& doc, const std::string& file,
                                             const std::vector<std::string>& swept);

// The same, thrown as one config::ScenarioError holding every message when there is any. The
// swept keys are read from the document's [[sweep]] tables.
void check_scenario_keys(const toml::table& doc, const std::string& file);

}  // namespace ncosim::sim
