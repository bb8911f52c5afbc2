// config/run_settings.h — the [run] table's values (horizon, runs, seed, period, re-centring):
// what a campaign is made of, read by the scenario reader (sim/scenario/scenario_sections.cc) and
// by the components that must know the horizon before t = 0 (the SUMO mobility source records that
// many periods). Plain data: the ranges are checked where it is read. The defaults are declared
// with the keys (sim/scenario/scenario_keys.cc run_keys()), and read_run() takes them from there;
// the initialisers below are for code that builds settings without a scenario (sumo/traffic.cc),
// and a test (tests/sim/scenario_sections_test.cc ReadRun) checks that they equal the declarations.
#pragma once

#include <cstdint>
#include <string>

namespace ncosim::config {

struct RunSettings {
  std::int64_t periods = 10000;
  std::int64_t warmup = 100;
  std::int64_t runs = 10;
  std::uint64_t seed = 1;
  double period = 1.0;            // seconds
  std::string recentre = "auto";  // auto | always | never
  bool error_curve = false;       // the run-averaged error against time (error_curve.csv)
};

}  // namespace ncosim::config
