// sim/cmd/cli.h — the ncosim command line: run, design, check, list.
// Exit status: 0 success, 2 bad input (scenario or command line), 1 anything else.
#pragma once

#include <nlohmann/json.hpp>
#include <string>

#include "sim/scenario/scenario.h"

namespace ncosim::sim {

int run_cli(int argc, char** argv);

}  // namespace ncosim::sim
