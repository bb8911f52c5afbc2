// main.cc — the ncosim command line with this example's kinds added: one add_extension() call
// before run_cli(). `my_ncosim list` shows them beside the built-ins; every command works.
#include "kinds.h"
#include "sim/cmd/cli.h"
#include "sim/scenario/extensions.h"

int main(int argc, char** argv) {
  ncosim::sim::add_extension([](ncosim::sim::Registries& r) {
    register_alpha_beta(r.estimators);
    register_mass_spring_damper(r.plants);
    register_periodic_outage(r.links);
    register_deadband_heartbeat(r.send_policies);
  });
  return ncosim::sim::run_cli(argc, argv);
}
