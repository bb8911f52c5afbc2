// estimators/estimator.cc — shared helpers and the one place where built-in kinds register.
#include "estimators/estimator.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <variant>

#include "estimators/kinds.h"

namespace ncosim::est {

std::vector<double> SensorModel::delay_pmf(int max_delay) const {
  if (link == nullptr) {
    std::vector<double> pmf(static_cast<std::size_t>(max_delay) + 1, 0.0);
    pmf[0] = 1.0;
    return pmf;
  }
  return link->delay_pmf(max_delay);
}

Eigen::Index Model::total_outputs() const {
  Eigen::Index n = 0;
  for (const auto& s : sensors) n += s.spec.ny();
  return n;
}

int Model::mode_count() const {
  if (!plant.modes.empty()) return static_cast<int>(plant.modes.size());
  if (!actuators.empty()) return 1 << actuators.size();
  return 0;
}

bool Model::is_nonlinear() const {
  if (plant.nonlinear) return true;
  return std::any_of(sensors.begin(), sensors.end(),
                     [](const SensorModel& s) { return s.spec.h != nullptr; });
}

const config::Keys& initial_keys() {
  using config::Key;
  static const config::Keys keys{
      Key::vector("xhat0")
          .optional("the plant's x0")
          .help("initial estimate, n entries (copied into every block of a delay-extended "
                "estimate)"),
      Key::matrix("P0").optional("zeros").help(
          "initial error covariance, n x n, symmetric positive semidefinite"),
  };
  return keys;
}

InitialEstimate read_initial(const config::Table& t, const Model& model) {
  const config::KeyReader r(t, initial_keys());
  const Eigen::Index n = model.plant.n();
  InitialEstimate init{model.plant.x0, Eigen::MatrixXd::Zero(n, n)};
  if (r.has("xhat0")) {
    init.xhat0 = r.vector("xhat0");
    if (init.xhat0.size() != n) {
      t.fail("xhat0",
             fmt::format("expected {} entries (the state size), got {}", n, init.xhat0.size()));
    }
  }
  if (r.has("P0")) {
    init.P0 = r.matrix("P0");
    config::require_shape(t, "P0", init.P0, n, n);
    config::require_psd(t, "P0", init.P0);
  }
  return init;
}

config::Key max_delay_key() {
  return config::Key::integer("max_delay")
      .range(0, 62)
      .unit("periods")
      .help("d-bar: samples with delay 0 .. max_delay are used, later ones discarded");
}

DesignCost generic_design_cost(const Model& model) {
  const double n = static_cast<double>(model.plant.n());
  return {16.0 * 8.0 * n * n, 200.0 * 2.0 * n * n * n, ""};
}

std::int64_t peek_integer(const toml::table& raw, const config::Key& key) {
  // The declared range, as integers (an open bound excludes its value).
  std::int64_t lo = std::numeric_limits<std::int64_t>::min() / 2;
  std::int64_t hi = std::numeric_limits<std::int64_t>::max() / 2;
  if (const auto b = key.lo()) {
    lo = static_cast<std::int64_t>(std::ceil(*b));
    if (key.lo_open() && static_cast<double>(lo) == *b) ++lo;
  }
  if (const auto b = key.hi()) {
    hi = static_cast<std::int64_t>(std::floor(*b));
    if (key.hi_open() && static_cast<double>(hi) == *b) --hi;
  }
  const auto* declared = std::get_if<std::int64_t>(&key.default_value());
  std::int64_t v = declared != nullptr ? *declared : key.lo() ? lo : 0;
  if (const toml::node* n = raw.get(key.name())) {
    if (auto i = n->value_exact<std::int64_t>()) {
      v = *i;
    } else if (auto d = n->value_exact<double>()) {
      if (std::isfinite(*d) && std::floor(*d) == *d && std::fabs(*d) < 1e9)
        v = static_cast<std::int64_t>(*d);
    }
  }
  return std::max(lo, std::min(v, hi));
}

std::string peek_string(const toml::table& raw, const config::Key& key) {
  if (const auto v = raw[key.name()].value_exact<std::string>()) return *v;
  const auto* declared = std::get_if<std::string>(&key.default_value());
  return declared != nullptr ? *declared : std::string();
}

DesignCost EstimatorRegistry::cost(std::string_view kind, const config::Table& t,
                                   const toml::table& raw, const Model& model,
                                   const std::string& state_driver) const {
  for (const auto& [name, estimate] : costs_) {
    if (name == kind && estimate) return estimate(t, raw, model, state_driver);
  }
  return generic_design_cost(model);
}

void register_estimators(EstimatorRegistry& registry) {
  register_jump(registry);
  register_kalman_extended(registry);
  register_open_loop(registry);
  register_imm(registry);
  register_mode_io(registry);
  register_mode_ss(registry);
  register_kalman_buffer(registry);
  register_static_buffer(registry);
  register_sod_kalman(registry);
  register_sod_jump(registry);
}

}  // namespace ncosim::est
