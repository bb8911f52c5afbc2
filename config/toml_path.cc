// config/toml_path.cc — key paths into a TOML document (config/toml_path.h).
#include "config/toml_path.h"

#include <fmt/format.h>

#include <optional>
#include <utility>
#include <vector>

#include "config/config.h"

namespace ncosim::config {

namespace {

struct PathSegment {
  std::string key;
  std::optional<std::size_t> index;
};

std::vector<PathSegment> parse_path(const std::string& path, const std::string& origin, int line) {
  std::vector<PathSegment> out;
  std::size_t i = 0;
  auto bad = [&](const std::string& why) {
    throw ScenarioError(format_error(origin, line, path, why));
  };
  while (i < path.size()) {
    std::size_t j = i;
    while (j < path.size() && path[j] != '.' && path[j] != '[') ++j;
    if (j == i) bad("expected a key path like 'estimator[0].history' or 'run.runs'");
    PathSegment seg{path.substr(i, j - i), std::nullopt};
    if (j < path.size() && path[j] == '[') {
      const std::size_t close = path.find(']', j);
      if (close == std::string::npos) bad("expected ']' in the key path");
      const std::string idx = path.substr(j + 1, close - j - 1);
      if (idx.empty() || idx.find_first_not_of("0123456789") != std::string::npos) {
        bad(fmt::format("expected a 0-based index inside [], got '{}'", idx));
      }
      seg.index = std::stoul(idx);
      j = close + 1;
    }
    out.push_back(seg);
    if (j < path.size()) {
      if (path[j] != '.') bad("expected '.' between keys");
      ++j;
      if (j == path.size()) bad("the key path ends with '.'");
    }
    i = j;
  }
  if (out.empty()) bad("expected a key path");
  if (out.back().index) bad("expected the path to end with a key, not an index");
  return out;
}

// The table that holds the last key of `path` (intermediate tables are created).
toml::table& parent_of(toml::table& doc, const std::string& path,
                       const std::vector<PathSegment>& segs, const std::string& origin, int line) {
  toml::table* cur = &doc;
  std::string walked;
  for (std::size_t s = 0; s + 1 < segs.size(); ++s) {
    const auto& seg = segs[s];
    walked += (walked.empty() ? "" : ".") + seg.key;
    toml::node* n = cur->get(seg.key);
    if (seg.index) {
      toml::array* arr = n ? n->as_array() : nullptr;
      const std::size_t size = arr ? arr->size() : 0;
      if (*seg.index >= size) {
        throw ScenarioError(format_error(
            origin, line, path,
            fmt::format("there is no [[{}]] number {} (the scenario has {}; indices are 0-based)",
                        seg.key, *seg.index, size)));
      }
      toml::table* t = (*arr)[*seg.index].as_table();
      if (t == nullptr) {
        throw ScenarioError(format_error(origin, line, path,
                                         fmt::format("'{}' is not an array of tables", walked)));
      }
      cur = t;
      walked += fmt::format("[{}]", *seg.index);
    } else {
      if (n == nullptr) {
        cur->insert(seg.key, toml::table{});
        n = cur->get(seg.key);
      }
      if (!n->is_table()) {
        throw ScenarioError(
            format_error(origin, line, path, fmt::format("'{}' is not a table", walked)));
      }
      cur = n->as_table();
    }
  }
  return *cur;
}

}  // namespace

void set_path(toml::table& doc, const std::string& path, const toml::node& value,
              const std::string& origin, int line) {
  const auto segs = parse_path(path, origin, line);
  parent_of(doc, path, segs, origin, line).insert_or_assign(segs.back().key, value);
}

void set_path(toml::table& doc, const std::string& path, toml::node&& value,
              const std::string& origin, int line) {
  const auto segs = parse_path(path, origin, line);
  // Moving keeps the value's source (file and line, or command-line origin) for error messages;
  // toml++ drops it on copies.
  parent_of(doc, path, segs, origin, line).insert_or_assign(segs.back().key, std::move(value));
}

void apply_set(toml::table& doc, const std::string& assignment, const std::string& origin) {
  const std::size_t eq = assignment.find('=');
  if (eq == std::string::npos || eq == 0) {
    throw ScenarioError(
        format_error(origin, 0, "", fmt::format("expected KEY=VALUE, got '{}'", assignment)));
  }
  std::string key = assignment.substr(0, eq);
  while (!key.empty() && key.back() == ' ') key.pop_back();
  while (!key.empty() && key.front() == ' ') key.erase(0, 1);
  toml::table parsed = parse_value(key, assignment.substr(eq + 1), origin);
  set_path(doc, key, std::move(*parsed.get("value")), origin, 0);
}

toml::table parse_value(const std::string& key, const std::string& text,
                        const std::string& origin) {
  try {
    return toml::parse("value = " + text, std::string_view(origin));
  } catch (const toml::parse_error& e) {
    throw ScenarioError(format_error(
        origin, 0, key,
        fmt::format("expected a TOML value (e.g. 4, 0.5, \"S4\", [0.9, 0.05]), got '{}': {}", text,
                    e.description())));
  }
}

const toml::node* find_path(const toml::table& doc, const std::string& path) {
  std::vector<PathSegment> segs;
  try {
    segs = parse_path(path, "", 0);
  } catch (const ScenarioError&) {
    return nullptr;
  }
  const toml::table* cur = &doc;
  for (std::size_t s = 0; s < segs.size(); ++s) {
    const toml::node* n = cur->get(segs[s].key);
    if (n == nullptr) return nullptr;
    if (segs[s].index) {
      const toml::array* arr = n->as_array();
      if (arr == nullptr || *segs[s].index >= arr->size()) return nullptr;
      n = arr->get(*segs[s].index);
    }
    if (s + 1 == segs.size()) return n;
    cur = n->as_table();
    if (cur == nullptr) return nullptr;
  }
  return nullptr;
}

}  // namespace ncosim::config
