// tests/fuzz/scenario_reader_fuzz.cc — coverage-guided fuzz target (libFuzzer) for the scenario
// reader: the input is a scenario file, loaded as `ncosim check` loads it (parse, sweeps, every
// case built and designed) under small resource limits. A crash, a sanitizer report, an
// exception that is not ScenarioError, or a ScenarioError whose message does not start with
// FILE:LINE aborts (a finding). Built only by scripts/fuzz_scenario_reader.sh (clang 14,
// -fsanitize=fuzzer,address), never in CI; every crasher becomes a regression test.
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>

#include "sim/scenario/resource_limits.h"
#include "sim/scenario/scenario.h"

namespace {

const std::string& scenario_path() {
  static const std::string path = [] {
    const auto dir = std::filesystem::temp_directory_path() /
                     ("ncosim_reader_fuzz_" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir);
    ncosim::sim::set_resource_limits({2e8, 2e9});  // 200 MB, 2 GFLOP per design
    return (dir / "s.toml").string();
  }();
  return path;
}

bool starts_with_file_line(const char* what, const std::string& file) {
  if (std::strncmp(what, file.c_str(), file.size()) != 0 || what[file.size()] != ':') return false;
  const char* p = what + file.size() + 1;
  if (*p < '0' || *p > '9') return false;
  while (*p >= '0' && *p <= '9') ++p;
  return *p == ':';
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string& path = scenario_path();
  {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  }
  try {
    (void)ncosim::sim::load_cases(path, {});
  } catch (const ncosim::config::ScenarioError& e) {
    if (!starts_with_file_line(e.what(), path)) {
      std::fprintf(stderr, "exit-2 message without FILE:LINE: %s\n", e.what());
      std::abort();
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "not a ScenarioError: %s\n", e.what());
    std::abort();
  }
  return 0;
}
