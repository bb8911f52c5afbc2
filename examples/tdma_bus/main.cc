// main.cc — the ncosim command line with the `tdma_bus` network kind added: one add_extension()
// call before run_cli(). `my_tdma list --keys network.tdma_bus` shows its keys; every command
// (run, check, record-link, ...) works on a scenario whose [[network]] is a tdma_bus.
#include "sim/cmd/cli.h"
#include "sim/scenario/extensions.h"
#include "tdma_bus.h"

int main(int argc, char** argv) {
  ncosim::sim::add_extension([](ncosim::sim::Registries& r) { register_tdma_bus(r.networks); });
  return ncosim::sim::run_cli(argc, argv);
}
