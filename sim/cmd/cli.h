// sim/cmd/cli.h — the ncosim command line: run, design, check, list.
// Exit status: 0 success, 2 bad input (scenario or command line), 1 anything else.
#pragma once

#include <nlohmann/json.hpp>
#include <string>

#include "sim/run/progress.h"
#include "sim/scenario/scenario.h"

namespace ncosim::sim {

int run_cli(int argc, char** argv);

// What a program that embeds the command line (the Python module, python/) changes in it.
struct CliHooks {
  // `run`: the campaign's progress goes to this observer instead of the line on stderr.
  CampaignProgress::Observer progress;
  // The ncosim executable that the SUMO live workers and the network workers start (`ncosim
  // sumo-live`, `ncosim network-worker`); empty: this process's own executable, which an
  // embedding interpreter is not.
  std::string worker_executable;
  // `run`: a second SIGINT/SIGTERM ends the process at once (the command line), or, false, only
  // stops the campaign as the first did (an interpreter whose end would lose the user's session).
  bool second_signal_aborts = true;
};
int run_cli(int argc, char** argv, const CliHooks& hooks);

}  // namespace ncosim::sim
