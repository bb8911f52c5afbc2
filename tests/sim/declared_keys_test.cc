// tests/sim/declared_keys_test.cc — the declared keys of every registered kind (config/keys.h):
// each key has a one-line help and a unique name, and a declared default lies in its range and
// among its values (so the docs' default is one the reader accepts).
#include <gtest/gtest.h>

#include <algorithm>
#include <set>
#include <string>
#include <variant>

#include "config/keys.h"
#include "sim/scenario/registries.h"
#include "sim/scenario/scenario_keys.h"

namespace ncosim::sim {
namespace {

void check_keys(const std::string& kind, const config::Keys& keys) {
  std::set<std::string> names;
  for (const config::Key& k : keys.list()) {
    EXPECT_TRUE(names.insert(k.name()).second) << kind << ": key " << k.name() << " twice";
    EXPECT_FALSE(k.help_text().empty()) << kind << ": key " << k.name() << " has no help";
    const config::Key::Value& d = k.default_value();
    if (const auto* v = std::get_if<double>(&d)) {
      EXPECT_TRUE(k.in_range(*v)) << kind << "." << k.name();
    }
    if (const auto* v = std::get_if<std::int64_t>(&d)) {
      EXPECT_TRUE(k.in_range(static_cast<double>(*v))) << kind << "." << k.name();
    }
    if (const auto* v = std::get_if<std::string>(&d); v && k.type() == config::KeyType::kChoice) {
      EXPECT_NE(std::find(k.values().begin(), k.values().end(), *v), k.values().end())
          << kind << "." << k.name();
    }
    if (k.fields() != nullptr) check_keys(kind + "." + k.name(), *k.fields());
  }
}

template <class R>
int check_registry(const char* prefix, const R& registry) {
  int declared = 0;
  for (const auto& e : registry.entries()) {
    check_keys(std::string(prefix) + "." + e.name, e.keys);
    declared += e.keys.empty() ? 0 : 1;
  }
  return declared;
}

TEST(DeclaredKeys, EveryKeyHasHelpAndAValidDefault) {
  EXPECT_GE(check_registry("plant", plant_registry()), 4);
  EXPECT_GE(check_registry("link", link_registry()), 7);
  EXPECT_GE(check_registry("input", input_registry()), 4);
  check_registry("estimator", estimator_registry());
  EXPECT_GE(check_registry("send_policy", send_policy_registry()), 1);
}

// A table key without fields leaves its sub-table open to any key (neither the key check nor the
// schema could flag a typo in it).
void expect_fields(const std::string& where, const config::Keys& keys) {
  for (const config::Key& k : keys.list()) {
    const bool table = k.type() == config::KeyType::kTable || k.type() == config::KeyType::kTables;
    if (!table) continue;
    if (k.fields() == nullptr) {
      // Key paths of the user's choosing (sweep keys): open by design.
      EXPECT_EQ(where + "." + k.name(), "paired.reference_case") << "declares no fields";
      continue;
    }
    expect_fields(where + "." + k.name(), *k.fields());
  }
}

// Every section and every built-in kind is closed: each kind declared its keys (even none, as the
// periodic policy), and every table key declares its fields (issue 40 part 4).
TEST(DeclaredKeys, EverySectionKindAndSubTableIsClosed) {
  int kinds = 0;
  for (const Section& sec : scenario_sections()) {
    ASSERT_NE(sec.keys, nullptr) << sec.key;
    EXPECT_TRUE(sec.closed) << sec.key;
    expect_fields(sec.key, *sec.keys);
    for (const SectionKind& kind : sec.kinds) {
      ++kinds;
      EXPECT_TRUE(kind.declared) << sec.key << " kind " << kind.name;
      expect_fields(sec.key + "." + kind.name, *kind.keys);
    }
  }
  EXPECT_GE(kinds, 30);
}

}  // namespace
}  // namespace ncosim::sim
