// tests/error_of.h — in-process tests of bad input: a TOML text parsed as the file "s.toml",
// and the message of the ScenarioError a call throws. Configuration layer only.
#pragma once

#include <string>
#include <string_view>

#include "config/config.h"

namespace ncosim::testing {

inline toml::table parse_toml(const std::string& text) {
  return toml::parse(text, std::string_view("s.toml"));
}

// The ScenarioError message that `f` throws ("" when it throws none).
template <class F>
std::string error_of(F&& f) {
  try {
    f();
  } catch (const config::ScenarioError& e) {
    return e.what();
  }
  return "";
}

}  // namespace ncosim::testing
