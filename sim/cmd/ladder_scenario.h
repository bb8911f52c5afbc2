// sim/cmd/ladder_scenario.h — the scenario files `ncosim ladder` writes (sim/cmd/ladder.h): the
// user's scenario as the ladder ran it (--set and --runs/--periods/--seed applied), with its
// network links given the fitted design law (the network rung) or replaced by fitted links, the
// [[network]] and [[background]] tables dropped (a surrogate rung). They are ordinary scenario
// files: `ncosim run` runs them alone.
//
// The text is written from the parsed document: every table and key in the order of the file
// (values an option set come last in their table), numbers in their shortest exact form; the
// file's comments are not kept. A relative path that names a file the scenario read is rewritten
// relative to the folder the files are written to.
#pragma once

#include <toml++/toml.h>

#include <map>
#include <string>
#include <vector>

#include "config/input_files.h"

namespace ncosim::sim {

// The document a ladder's scenarios are written from: `text` parsed as `file`, `sets` applied,
// then [run] runs, periods and seed when given (> 0, or set). Throws ScenarioError.
toml::table ladder_document(const std::string& file, const std::string& text,
                            const std::vector<std::string>& sets, std::int64_t runs,
                            std::int64_t periods, const std::optional<std::uint64_t>& seed);

// Rewrites every string value of `doc` that is a relative path to one of `inputs` (paths
// relative to the scenario's folder `scenario_dir`, as config/input_files.h records them) into
// a path relative to `out_dir`.
void rebase_input_paths(toml::table& doc, const config::InputFiles& inputs,
                        const std::string& scenario_dir, const std::string& out_dir);

// The TOML text of `doc`, in the file's order (`file`: the document's source name, whose
// positions order the keys). `replace`: per [[link]] index, the text that stands for that table
// (a fitted link's table from its `[[link]]` line on); `drop`: top-level keys left out.
std::string scenario_text(const toml::table& doc, const std::string& file,
                          const std::map<std::size_t, std::string>& replace,
                          const std::vector<std::string>& drop);

}  // namespace ncosim::sim
