// sim/registry.cc — the one place where built-in kinds are registered (explicit calls: static
// self-registration can be dropped by the linker from static libraries).
#include "sim/registries.h"

#if NCOSIM_HAVE_SUMO
#include "sumo/sumo.h"
#endif

namespace ncosim::sim {

const models::PlantRegistry& plant_registry() {
  static const models::PlantRegistry r = [] {
    models::PlantRegistry reg;
    models::register_plants(reg);
#if NCOSIM_HAVE_SUMO
    sumo::register_plants(reg);
#endif
    return reg;
  }();
  return r;
}

const models::LinkRegistry& link_registry() {
  static const models::LinkRegistry r = [] {
    models::LinkRegistry reg;
    models::register_links(reg);
#if NCOSIM_HAVE_SUMO
    sumo::register_links(reg);
#endif
    return reg;
  }();
  return r;
}

const models::InputRegistry& input_registry() {
  static const models::InputRegistry r = [] {
    models::InputRegistry reg;
    models::register_inputs(reg);
    return reg;
  }();
  return r;
}

const est::EstimatorRegistry& estimator_registry() {
  static const est::EstimatorRegistry r = [] {
    est::EstimatorRegistry reg;
    est::register_estimators(reg);
    return reg;
  }();
  return r;
}

bool have_sumo() { return NCOSIM_HAVE_SUMO != 0; }

void announce_mobility(const toml::table& case_doc, const std::string& file, const std::string& dir) {
#if NCOSIM_HAVE_SUMO
  sumo::announce_vehicles(case_doc, file, dir);
#else
  (void)case_doc, (void)file, (void)dir;
#endif
}

std::shared_ptr<MobilitySource> make_mobility(const Table& t, const RunSettings& run, const std::string& dir) {
#if NCOSIM_HAVE_SUMO
  return sumo::make_mobility(t, run, dir);
#else
  (void)run, (void)dir;
  t.fail_here("this ncosim was built without SUMO (configure with -DNCOSIM_SUMO=ON and libsumo installed)");
#endif
}

}  // namespace ncosim::sim
