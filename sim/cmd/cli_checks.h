// sim/cmd/cli_checks.h — option checks that several commands share (sim/cmd/cli.cc, ladder.cc).
#pragma once

#include <CLI/CLI.hpp>

namespace ncosim::sim {

// A seed as written: decimal digits, 0 .. 2^63 - 1 (what run.seed, a TOML integer, can hold).
// CLI::Range on an int64 would see a larger number clamped to 2^63 - 1 by the conversion: two
// different requests would run the same campaign.
CLI::Validator seed_range();

}  // namespace ncosim::sim
