// sim/registry.cc — the one place where built-in kinds are registered (explicit calls: static
// self-registration can be dropped by the linker from static libraries).
#include "sim/registries.h"

namespace ncosim::sim {

const models::PlantRegistry& plant_registry() {
  static const models::PlantRegistry r = [] {
    models::PlantRegistry reg;
    models::register_plants(reg);
    return reg;
  }();
  return r;
}

const models::LinkRegistry& link_registry() {
  static const models::LinkRegistry r = [] {
    models::LinkRegistry reg;
    models::register_links(reg);
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

}  // namespace ncosim::sim
