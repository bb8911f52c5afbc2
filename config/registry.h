// config/registry.h — one registry per component kind: a name, a one-line help, the kind's
// declared keys (config/keys.h; empty for a kind that declares none) and a factory that reads its
// own table. A failed lookup lists the valid names (with a did-you-mean).
// Built-ins are registered by explicit calls from one place (sim/scenario/registries.cc).
#pragma once

#include <fmt/format.h>

#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include "config/config.h"
#include "config/keys.h"

namespace ncosim::config {

// "expected one of "a", "b", got "c" (did you mean "a"?)": a kind that is not among `names`.
inline std::string unknown_kind_message(std::string_view kind,
                                        const std::vector<std::string>& names) {
  std::string list;
  for (const auto& n : names) list += (list.empty() ? "" : ", ") + fmt::format("\"{}\"", n);
  const std::string hint = did_you_mean(kind, names);
  return fmt::format("expected one of {}, got \"{}\"{}", list, kind,
                     hint.empty() ? "" : fmt::format(" (did you mean \"{}\"?)", hint));
}

template <class Product, class... Args>
class Registry {
 public:
  using Factory = std::function<Product(const Table&, Args...)>;
  struct Entry {
    std::string name;
    std::string help;
    Factory factory;
    Keys keys;  // the kind's own keys (not the section's common ones)
    // The kind declared its keys (even none): its table holds no other key beside the section's
    // common ones, so key checks and the schema treat it as closed. False for a kind registered
    // without declarations (its reader alone knows its keys).
    bool declared = false;
  };

  void add(std::string name, std::string help, Factory factory) {
    entries_.push_back(Entry{std::move(name), std::move(help), std::move(factory), {}, false});
  }
  // A kind that declares its keys: its factory reads them through a KeyReader over `keys`.
  void add(std::string name, std::string help, Keys keys, Factory factory) {
    entries_.push_back(
        Entry{std::move(name), std::move(help), std::move(factory), std::move(keys), true});
  }

  const Entry* find(std::string_view name) const {
    for (const auto& e : entries_) {
      if (e.name == name) return &e;
    }
    return nullptr;
  }

  std::vector<std::string> names() const {
    std::vector<std::string> out;
    for (const auto& e : entries_) out.push_back(e.name);
    return out;
  }

  // The entry named by table key `key` (default `fallback` when absent); a ScenarioError
  // listing the valid kinds when unknown.
  const Entry& lookup(const Table& t, std::string_view key, std::string_view fallback) const {
    const std::string kind = t.has(key) || fallback.empty() ? t.string(key) : std::string(fallback);
    if (const Entry* e = find(kind)) return *e;
    t.fail(key, unknown_kind_message(kind, names()));
  }

  const std::vector<Entry>& entries() const { return entries_; }

 private:
  std::vector<Entry> entries_;
};

}  // namespace ncosim::config
