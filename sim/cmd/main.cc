// sim/cmd/main.cc — the ncosim executable.
#include "sim/cmd/cli.h"

int main(int argc, char** argv) { return ncosim::sim::run_cli(argc, argv); }
