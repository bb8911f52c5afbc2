// sim/scenario/scenario_check.cc — every independent error of a scenario at once
// (sim/scenario/scenario_check.h).
#include "sim/scenario/scenario_check.h"

#include <fmt/format.h>

#include <algorithm>

#include "config/key_check.h"
#include "config/registry.h"
#include "sim/scenario/scenario_keys.h"

namespace ncosim::sim {

namespace {

using config::LineError;

// `a` followed by the keys of `b` that `a` does not declare; `skip` left out.
config::Keys joined(const config::Keys& a, const config::Keys* b, const std::string& skip = "") {
  std::vector<config::Key> keys;
  for (const config::Key& k : a.list()) {
    if (k.name() != skip) keys.push_back(k);
  }
  if (b != nullptr) {
    for (const config::Key& k : b->list()) {
      if (a.find(k.name()) == nullptr) keys.push_back(k);
    }
  }
  config::Keys out(std::move(keys));
  for (const auto& group : a.one_of()) out.require_one_of(group);
  if (b != nullptr) {
    for (const auto& group : b->one_of()) out.require_one_of(group);
  }
  return out;
}

// The kind of section table `t` (nullptr when its kind key is wrong: the error appended).
const SectionKind* kind_of(const config::Table& t, const Section& sec,
                           const config::KeyCheckOptions& options, std::vector<LineError>& errors) {
  const std::string path = t.key_path(sec.kind_key);
  const bool swept =
      std::any_of(options.set_elsewhere.begin(), options.set_elsewhere.end(),
                  [&](const std::string& s) { return config::path_inside(s, path); });
  if (swept) return nullptr;  // judged in every sweep case
  try {
    if (!t.has(sec.kind_key) && sec.default_kind.empty())
      (void)t.string(sec.kind_key);  // "got nothing (the key is required)"
    const std::string name = t.has(sec.kind_key) ? t.string(sec.kind_key) : sec.default_kind;
    std::vector<std::string> names;
    for (const SectionKind& k : sec.kinds) {
      if (k.name == name) return &k;
      names.push_back(k.name);
    }
    t.fail(sec.kind_key, config::unknown_kind_message(name, names));
  } catch (const config::ScenarioError& e) {
    errors.push_back({t.line_of(sec.kind_key), e.what()});
  }
  return nullptr;
}

void check_section_table(const config::Table& t, const Section& sec,
                         const config::KeyCheckOptions& options, std::vector<LineError>& errors) {
  if (sec.kind_key.empty()) {
    config::check_table(t, *sec.keys, sec.closed, options, errors);
    return;
  }
  const SectionKind* kind = kind_of(t, sec, options, errors);
  if (kind == nullptr) {  // its other keys cannot be judged: the common ones only
    config::check_table(t, joined(*sec.keys, nullptr, sec.kind_key), false, options, errors);
    return;
  }
  const bool closed = sec.closed && kind->declared;
  config::check_table(t, joined(*sec.keys, kind->keys), closed, options, errors);
}

// The tables of section `sec` in `root` (none when absent or of the wrong type: the error
// appended, with a missing required section's).
std::vector<config::Table> section_tables(const config::Table& root, const Section& sec,
                                          const config::KeyCheckOptions& options,
                                          std::vector<LineError>& errors) {
  std::vector<config::Table> tables;
  try {
    if (sec.array)
      tables = root.tables(sec.key);
    else if (root.has(sec.key))
      tables.push_back(root.table(sec.key));
  } catch (const config::ScenarioError& e) {
    errors.push_back({root.line_of(sec.key), e.what()});
    return {};
  }
  const bool provided =
      std::any_of(options.set_elsewhere.begin(), options.set_elsewhere.end(),
                  [&](const std::string& s) { return config::path_inside(s, sec.key); });
  if (tables.empty() && sec.required && !provided) {
    errors.push_back({root.line_of(sec.key),
                      config::format_error(root.file(), 1, sec.key, missing_section_message(sec))});
  }
  return tables;
}

// The `key` of every [[sweep]] table that has a string one.
std::vector<std::string> swept_keys(const toml::table& doc) {
  std::vector<std::string> out;
  if (const toml::array* sweeps = doc["sweep"].as_array()) {
    for (const toml::node& s : *sweeps) {
      if (const toml::table* t = s.as_table()) {
        if (const auto key = (*t)["key"].value_exact<std::string>()) out.push_back(*key);
      }
    }
  }
  return out;
}

}  // namespace

std::vector<std::string> scenario_key_errors(const toml::table& doc, const std::string& file,
                                             const std::vector<std::string>& swept) {
  config::KeyCheckOptions options;
  options.set_elsewhere = swept;
  options.note =
      " (in the base scenario: the values written outside [[sweep]] must be valid too, even where "
      "a sweep replaces them)";
  const config::Table root(doc, "", file);
  std::vector<LineError> errors;
  // The top level: unknown tables and keys, the keys that are not sections (title).
  const std::vector<Section> sections = scenario_sections();
  const config::KeyReader top(root, top_level_keys());
  std::vector<std::string> names;
  for (const config::Key& k : top_level_keys().list()) {
    names.push_back(k.name());
    const bool section = std::any_of(sections.begin(), sections.end(),
                                     [&](const Section& s) { return s.key == k.name(); });
    if (!section) config::check_key(root, top, k, options, errors);
  }
  for (LineError& e : root.unknown_keys(names)) errors.push_back(std::move(e));
  for (const Section& sec : sections) {
    const std::vector<config::Table> tables = section_tables(root, sec, options, errors);
    if (sec.keys == nullptr) continue;  // read by its own reader
    for (const config::Table& t : tables) check_section_table(t, sec, options, errors);
  }
  return config::in_file_order(std::move(errors));
}

void check_scenario_keys(const toml::table& doc, const std::string& file) {
  std::vector<std::string> errors = scenario_key_errors(doc, file, swept_keys(doc));
  if (errors.size() == 1) throw config::ScenarioError(errors.front());
  if (!errors.empty()) throw config::ScenarioError(std::move(errors));
}

}  // namespace ncosim::sim
