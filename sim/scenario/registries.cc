// sim/scenario/registries.cc — the one place where built-in kinds are registered (explicit calls:
// static self-registration can be dropped by the linker from static libraries), then the extensions
// added by add_extension().
#include "sim/scenario/registries.h"

#include <fmt/format.h>

#include <mutex>
#include <stdexcept>
#include <vector>

#include "network/network.h"
#include "sim/scenario/extensions.h"

#if NCOSIM_HAVE_SUMO
#include "sumo/sumo.h"
#endif

namespace ncosim::sim {

namespace {

std::mutex& extension_mutex() {
  static std::mutex m;
  return m;
}
std::vector<Extension>& extensions() {
  static std::vector<Extension> v;
  return v;
}
bool& registries_built() {
  static bool built = false;
  return built;
}

template <class R>
void check_unique(const R& registry, const char* what) {
  const auto names = registry.names();
  for (std::size_t i = 0; i < names.size(); ++i) {
    for (std::size_t j = 0; j < i; ++j) {
      if (names[i] == names[j]) {
        throw std::logic_error(fmt::format("{} kind \"{}\" is registered twice", what, names[i]));
      }
    }
  }
}

struct AllRegistries {
  models::PlantRegistry plants;
  models::LinkRegistry links;
  models::InputRegistry inputs;
  est::EstimatorRegistry estimators;
  models::SendPolicyRegistry send_policies;
  network::NetworkRegistry networks;
};

AllRegistries& mutable_registries() {
  static AllRegistries r = [] {
    AllRegistries a;
    models::register_plants(a.plants);
    models::register_links(a.links);
    models::register_inputs(a.inputs);
    est::register_estimators(a.estimators);
    models::register_send_policies(a.send_policies);
    network::register_networks(a.networks);
    network::register_network_links(a.links);
#if NCOSIM_HAVE_SUMO
    sumo::register_plants(a.plants);
    sumo::register_links(a.links);
    // The network layer's keys that name vehicles (it does not know SUMO).
    sumo::declare_vehicle_keys(sumo::VehicleTable::kLink, "network", {"vehicle"});
    sumo::declare_vehicle_keys(sumo::VehicleTable::kNetwork, "", {"sink_vehicle"});
#endif
    std::lock_guard<std::mutex> lock(extension_mutex());
    Registries view{a.plants, a.links, a.inputs, a.estimators, a.send_policies, a.networks};
    for (const auto& e : extensions()) e(view);
    registries_built() = true;
    check_unique(a.plants, "plant");
    check_unique(a.links, "link");
    check_unique(a.inputs, "input");
    check_unique(a.estimators, "estimator");
    check_unique(a.send_policies, "send policy");
    check_unique(a.networks, "network");
    return a;
  }();
  return r;
}

const AllRegistries& all_registries() { return mutable_registries(); }

}  // namespace

void add_extension_now(const Extension& extension) {
  AllRegistries& a = mutable_registries();
  std::lock_guard<std::mutex> lock(extension_mutex());
  // Into copies first: a name registered twice leaves the registries as they were.
  AllRegistries next = a;
  Registries view{next.plants,     next.links,         next.inputs,
                  next.estimators, next.send_policies, next.networks};
  extension(view);
  check_unique(next.plants, "plant");
  check_unique(next.links, "link");
  check_unique(next.inputs, "input");
  check_unique(next.estimators, "estimator");
  check_unique(next.send_policies, "send policy");
  check_unique(next.networks, "network");
  a = std::move(next);
}

void add_extension(Extension extension) {
  std::lock_guard<std::mutex> lock(extension_mutex());
  if (registries_built()) {
    throw std::logic_error(
        "ncosim::sim::add_extension: called after the registries were first used");
  }
  extensions().push_back(std::move(extension));
}

const models::PlantRegistry& plant_registry() { return all_registries().plants; }
const models::LinkRegistry& link_registry() { return all_registries().links; }
const models::InputRegistry& input_registry() { return all_registries().inputs; }
const est::EstimatorRegistry& estimator_registry() { return all_registries().estimators; }
const models::SendPolicyRegistry& send_policy_registry() { return all_registries().send_policies; }
const network::NetworkRegistry& network_registry() { return all_registries().networks; }

bool have_sumo() { return NCOSIM_HAVE_SUMO != 0; }

void announce_mobility(const toml::table& case_doc, const std::string& file,
                       const std::string& dir) {
#if NCOSIM_HAVE_SUMO
  (void)all_registries();  // the kinds declare their vehicle keys when they register
  sumo::announce_vehicles(case_doc, file, dir);
#else
  (void)case_doc, (void)file, (void)dir;
#endif
}

std::shared_ptr<models::MobilitySource> make_mobility(const config::Table& t,
                                                      const config::RunSettings& run,
                                                      const std::string& dir) {
#if NCOSIM_HAVE_SUMO
  return sumo::make_mobility(t, run, dir);
#else
  (void)run, (void)dir;
  t.fail_here(
      "this ncosim was built without SUMO (configure with -DNCOSIM_SUMO=ON and libsumo installed)");
#endif
}

}  // namespace ncosim::sim
