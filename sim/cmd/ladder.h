// sim/cmd/ladder.h — `ncosim ladder FILE`: the fidelity ladder of a network scenario in one
// command. Is a fitted statistical link a fair stand-in for the packet-level network, and how
// much faster is it?
//
//  1. record: every network link of FILE ([[link]] kind "network") is recorded as `ncosim
//     record-link` does (each run the campaign's run, the whole network simulated; no design_pmf
//     needed), into OUT/traces/<link>.csv;
//  2. fit: each link's trace (the scored periods, k >= warmup, of every run one after the other)
//     is fitted by every --family as `ncosim fit` does (OUT/fits/<link>.json); the `delay` fit
//     (the link's marginal delay law, packets independent) gives design_pmf;
//  3. scenarios: OUT/network.toml is FILE with every network link's design_pmf set to that law;
//     OUT/<family>.toml is the same with every network link replaced by its fitted link and the
//     [[network]] and [[background]] tables dropped (sim/cmd/ladder_scenario.h). A family that
//     cannot hold a trace (bernoulli when the delays vary) becomes a Bernoulli link with the
//     trace's loss and, for every delivered packet, its most common delay;
//  4. run: each scenario as `ncosim run` (same seed and runs: common random numbers for the plant
//     and the sensors' noise), into OUT/runs/<rung>/;
//  5. compare: each surrogate against the network, paired run by run, as `ncosim compare` does
//     (sim/analysis/compare.h; OUT/compare/<rung>.csv and .md), the verdicts printed per
//     estimator: where each surrogate leaves the band of +-tolerance around the network's MSE,
//     and how much faster its campaign ran (simulation wall time, manifest.json wall_seconds).
//
// OUT (default out/ladder_<file stem>) appears complete or not at all: everything is made in a
// hidden sibling folder and swapped in at the end (sim/files/output_set.h); an OUT that already
// holds files is refused without --replace. Bad input (the scenario, an option, a scenario
// without a network link or with [[sweep]] tables, a link that cannot be recorded) is refused
// before anything runs (exit 2, nothing written). Docs: docs/ladder.md.
#pragma once

#include <CLI/CLI.hpp>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace ncosim::sim {

struct LadderArgs {
  std::string file;
  std::vector<std::string> sets;
  std::string out;  // default: out/ladder_<file stem>
  std::int64_t runs = 0, periods = 0;
  std::int64_t seed = -1;             // -1: the file's
  std::vector<std::string> families;  // default: bernoulli, delay, gilbert_elliott, markov2
  double tolerance = 0.05;            // the band: relative change of the network's MSE
  double alpha = 0.05;                // compare's level
  int starts = 4;
  int max_iterations = 2000;
  int threads = 0;
  bool replace = false;
  bool quiet = false;
  std::string command_line;
};

// The subcommand and its own options (FILE, --set, --out and the resource limits are the
// command line's common ones: sim/cmd/cli.cc).
CLI::App* add_ladder_command(CLI::App& app, LadderArgs& args);

// The command: 0, or a campaign's exit status when one stopped (a signal); throws ScenarioError
// for bad input (exit 2), nothing written.
int cmd_ladder(const LadderArgs& args);

}  // namespace ncosim::sim
