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

}  // namespace
}  // namespace ncosim::sim
