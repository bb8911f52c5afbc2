// sim/cmd/codesign.cc
#include "sim/cmd/codesign.h"

#include <fmt/format.h>

#include <cstdio>
#include <ostream>

#include "estimators/sod_jump.h"

namespace ncosim::sim {

namespace {

std::vector<double> vec(const Eigen::VectorXd& v) { return {v.data(), v.data() + v.size()}; }

// One estimator's co-design as `ncosim codesign` prints it (results/README.md, codesign).
nlohmann::json codesign_json(const std::string& name, const est::SodJumpDesign& d,
                             const est::sod::CodesignSpec& spec,
                             const est::sod::SodDesignResult& z0, double mu,
                             const est::sod::CodesignResult& r, std::size_t sensors) {
  nlohmann::json j;
  j["estimator"] = name;
  j["design"] =
      d.spec().approach == est::sod::Approach::kDeterministic ? "deterministic" : "stochastic";
  j["gain"] = d.spec().jump ? "jump" : "constant";
  if (d.spec().approach == est::sod::Approach::kStochastic) {
    j["vertices"] = d.spec().vertices == est::sod::Vertices::kAll ? "all" : "lower";
    j["assumption"] = spec.assumption == est::sod::Assumption::kUniform ? "uniform" : "gaussian";
  } else {
    j["sigma2_delta_factor"] = spec.sigma2_factor;
  }
  j["r"] = vec(spec.r);
  j["z0"] = z0.bound;
  j["mu"] = mu;
  j["target"] = spec.target;
  j["epsilon"] = spec.epsilon;
  j["step"] = spec.relative_step ? "relative" : "absolute";
  j["delta0"] = vec(spec.delta0);
  j["status"] = r.status;
  j["delta"] = vec(r.delta);
  j["cost"] = r.cost;
  j["bound"] = r.design.ok ? nlohmann::json(r.design.bound) : nlohmann::json(nullptr);
  j["iterations"] = r.iterations;
  j["lmi_problems"] = r.lmi_problems;
  j["lmi_seconds"] = r.lmi_seconds;
  j["seconds"] = r.seconds;
  j["sdp_dimension"] = r.design.size.total_dimension;
  j["sdp_variables"] = r.design.size.variables;
  j["lmis_per_problem"] = r.design.lmis;
  nlohmann::json path = nlohmann::json::array();
  for (const auto& s : r.path)
    path.push_back({{"iteration", s.iteration},
                    {"delta", vec(s.delta)},
                    {"cost", s.cost},
                    {"bound", s.bound}});
  j["path"] = path;
  std::string sets;
  Eigen::Index row = 0;
  for (std::size_t s = 0; s < sensors; ++s, ++row) {
    sets += fmt::format("{}--set sensor[{}].delta={:.6g}", s ? " " : "", s, r.delta(row));
  }
  // Only thresholds that meet the target are worth applying.
  j["apply"] = r.status == "ok" ? nlohmann::json(sets) : nlohmann::json(nullptr);
  return j;
}

}  // namespace

nlohmann::json run_codesign(const Scenario& sc, const CodesignOptions& options) {
  nlohmann::json out = nlohmann::json::array();
  bool found = false;
  for (const auto& e : sc.estimators) {
    if (!options.estimator.empty() && e.name != options.estimator) continue;
    const est::SodJumpDesign* d = e.design->sod_codesign();
    if (d == nullptr) continue;
    found = true;
    const double mu = options.mu > 0.0 ? options.mu : d->mu();
    if (!(mu >= 1.0)) {
      throw config::ScenarioError(config::format_error(
          sc.file, 0, e.name, fmt::format("expected mu >= 1 ([codesign] mu or --mu), got {}", mu)));
    }
    const est::sod::SodDesignResult z0 = est::sod::design_all_measurements(d->system());
    if (!z0.ok)
      throw std::runtime_error(fmt::format("{}: the z~0 LMI failed ({})", e.name, z0.status));
    const auto spec = d->codesign_spec(mu, z0.bound);
    if (!spec) {
      throw config::ScenarioError(config::format_error(
          sc.file, 0, e.name, "expected one output per sensor for the co-design"));
    }
    auto progress = [&](const est::sod::CodesignStep& s) {
      if (!options.progress) return;
      std::fprintf(stderr, "%s: step %d  delta = [", e.name.c_str(), s.iteration);
      for (Eigen::Index i = 0; i < s.delta.size(); ++i)
        std::fprintf(stderr, "%s%.4g", i ? " " : "", s.delta(i));
      std::fprintf(stderr, "]  cost %.5g  bound %.5g (target %.5g)\n", s.cost, s.bound,
                   spec->target);
    };
    const est::sod::CodesignResult r = est::sod::codesign(d->system(), *spec, progress);
    out.push_back(codesign_json(e.name, *d, *spec, z0, mu, r, sc.model.sensors.size()));
  }
  if (!found) {
    throw config::ScenarioError(config::format_error(
        sc.file, 0, "estimator",
        options.estimator.empty()
            ? "expected at least one sod_jump estimator to co-design"
            : fmt::format("expected a sod_jump estimator named \"{}\"", options.estimator)));
  }
  return out;
}

std::string short_numbers(const nlohmann::json& array) {
  std::string out = "[";
  for (std::size_t i = 0; i < array.size(); ++i) {
    const auto& v = array[i];
    out += (i ? ", " : "") +
           (v.is_number() ? fmt::format("{:.6g}", v.get<double>()) : std::string(v.dump()));
  }
  return out + "]";
}

bool print_codesign(const nlohmann::json& j, std::ostream& os) {
  bool all_ok = true;
  for (const auto& e : j) {
    const std::string head = fmt::format(
        "{}: {} {} mu = {:.6g} (z0 = {:.5g}, target {:.5g})", e["estimator"].get<std::string>(),
        e["design"].get<std::string>(), e["gain"].get<std::string>(), e["mu"].get<double>(),
        e["z0"].get<double>(), e["target"].get<double>());
    const std::string bound = e["bound"].is_number()
                                  ? fmt::format("{:.5g}", e["bound"].get<double>())
                                  : std::string("not found (the LMI is infeasible)");
    if (e["status"] != "ok") {
      // Nothing to apply: say why instead of printing thresholds that miss the target.
      all_ok = false;
      os << fmt::format(
          "{}: status {}: the bound at delta0 = {} is {} (must be below the target); no "
          "thresholds to apply (raise --mu or lower delta0)\n",
          head, e["status"].get<std::string>(), short_numbers(e["delta0"]), bound);
      continue;
    }
    os << fmt::format(
        "{}: delta = {} cost {:.5g} bound {} [{} LMI problems, {:.2f} s solving, {:.2f} s total; "
        "epsilon {:.6g} {}, delta0 {}]\n  apply: {}\n",
        head, short_numbers(e["delta"]), e["cost"].get<double>(), bound,
        e["lmi_problems"].get<int>(), e["lmi_seconds"].get<double>(), e["seconds"].get<double>(),
        e["epsilon"].get<double>(), e["step"].get<std::string>(), short_numbers(e["delta0"]),
        e["apply"].get<std::string>());
  }
  return all_ok;
}

}  // namespace ncosim::sim
