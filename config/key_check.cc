// config/key_check.cc — every key-level error of a table at once (config/key_check.h).
#include "config/key_check.h"

#include <fmt/format.h>

#include <algorithm>

namespace ncosim::config {

bool path_inside(const std::string& a, const std::string& b) {
  return a == b || (a.size() > b.size() && a.compare(0, b.size(), b) == 0 &&
                    (a[b.size()] == '.' || a[b.size()] == '['));
}

namespace {

// Is the value at `path` (or around or inside it) set by another source?
bool set_elsewhere(const std::string& path, const KeyCheckOptions& options) {
  return std::any_of(
      options.set_elsewhere.begin(), options.set_elsewhere.end(),
      [&](const std::string& s) { return path_inside(s, path) || path_inside(path, s); });
}

// Reads key `k` of `t` with the getter of its type (the reader's own checks and messages); the
// sub-tables of a table key with fields are returned for checking within.
std::vector<Table> read_key(const KeyReader& r, const Key& k) {
  const std::string& name = k.name();
  if (!k.words().empty() && r.word(name)) return {};
  switch (k.type()) {
    case KeyType::kNumber:
      (void)r.number(name);
      break;
    case KeyType::kInteger:
      (void)r.integer(name);
      break;
    case KeyType::kBoolean:
      (void)r.boolean(name);
      break;
    case KeyType::kString:
    case KeyType::kChoice:
      (void)r.string(name);
      break;
    case KeyType::kNumbers:
    case KeyType::kVector:
      (void)r.numbers(name);
      break;
    case KeyType::kMatrix:
      (void)r.matrix(name);
      break;
    case KeyType::kRagged:
      (void)r.ragged(name);
      break;
    case KeyType::kTable:
      if (k.fields() != nullptr) return {r.table(name)};
      (void)r.table(name);
      break;
    case KeyType::kTables: {
      std::vector<Table> subs = r.tables(name);
      if (k.fields() != nullptr) return subs;
      break;
    }
    case KeyType::kArray:
      (void)r.array(name);
      break;
    case KeyType::kAny:
      break;  // the kind's own code reads it
  }
  return {};
}

}  // namespace

void check_key(const Table& t, const KeyReader& r, const Key& k, const KeyCheckOptions& options,
               std::vector<LineError>& errors) {
  const std::string path = t.key_path(k.name());
  if (!t.has(k.name())) {
    if (!k.required() || k.type() == KeyType::kAny || set_elsewhere(path, options)) return;
    if (k.type() == KeyType::kTables) {  // the getter reads an absent array as an empty one
      errors.push_back(
          {t.line(), format_error(t.file(), t.line(), path,
                                  fmt::format("expected an array of tables [[{}]], got nothing "
                                              "(the key is required)",
                                              path))});
      return;
    }
    try {
      (void)read_key(r, k);  // the getter's own "got nothing (the key is required)"
    } catch (const ScenarioError& e) {
      errors.push_back({t.line(), e.what()});
    }
    return;
  }
  std::vector<Table> subs;
  try {
    subs = read_key(r, k);
  } catch (const ScenarioError& e) {
    std::string message = e.what();
    if (set_elsewhere(path, options)) message += options.note;
    errors.push_back({t.line_of(k.name()), std::move(message)});
    return;
  }
  for (const Table& sub : subs) check_table(sub, *k.fields(), true, options, errors);
}

void check_table(const Table& t, const Keys& keys, bool closed, const KeyCheckOptions& options,
                 std::vector<LineError>& errors) {
  const KeyReader r(t, keys);
  std::vector<std::string> names;
  for (const Key& k : keys.list()) names.push_back(k.name());
  // The declared keys that this table's unknown keys are typos of ("sdt" for "std"): such a key
  // missing is the typo's error, told once (at the typo, with its did-you-mean).
  std::vector<std::string> meant;
  if (closed) {
    for (const auto& [key, value] : t.raw()) {
      if (std::find(names.begin(), names.end(), key.str()) != names.end()) continue;
      if (std::string hint = did_you_mean(key.str(), names); !hint.empty()) meant.push_back(hint);
    }
  }
  const auto typo_of = [&](const std::string& name) {
    return !t.has(name) && std::find(meant.begin(), meant.end(), name) != meant.end();
  };
  for (const Key& k : keys.list()) {
    if (!typo_of(k.name())) check_key(t, r, k, options, errors);
  }
  for (const auto& group : keys.one_of()) {
    const bool given = std::any_of(group.begin(), group.end(), [&](const std::string& k) {
      return t.has(k) || typo_of(k) || set_elsewhere(t.key_path(k), options);
    });
    if (!given) {
      errors.push_back(
          {t.line(), format_error(t.file(), t.line(), t.path(), Keys::one_of_error(group))});
    }
  }
  if (!closed) return;
  for (LineError& e : t.unknown_keys(names)) errors.push_back(std::move(e));
}

}  // namespace ncosim::config
