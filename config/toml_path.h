// config/toml_path.h — key paths into a TOML document ("estimator[0].history", "run.runs"):
// what `--set KEY=VALUE` and [[sweep]] keys name. Errors are ScenarioErrors naming the origin
// (the file and line, or the option) and the path.
#pragma once

#include <toml++/toml.h>

#include <string>

namespace ncosim::config {

// Applies `KEY=VALUE` (VALUE in TOML syntax) to `doc`. Throws ScenarioError.
void apply_set(toml::table& doc, const std::string& assignment, const std::string& origin);

// Sets the value at a key path ("estimator[0].history", "run.runs"); tables on the way are
// created, array elements must exist. Throws ScenarioError.
// The copying overload drops the value's source (toml++ copies never carry it); the moving
// one keeps it, so that later errors at the value point at where it came from.
void set_path(toml::table& doc, const std::string& path, const toml::node& value,
              const std::string& origin, int line);
void set_path(toml::table& doc, const std::string& path, toml::node&& value,
              const std::string& origin, int line);

// The value at a key path, or nullptr (also for a malformed path).
const toml::node* find_path(const toml::table& doc, const std::string& path);

// `value = TEXT` parsed with `origin` as the source path, so that errors at the value name the
// option that set it (see kCommandLineOrigin). Throws ScenarioError naming `key`.
toml::table parse_value(const std::string& key, const std::string& text, const std::string& origin);

}  // namespace ncosim::config
