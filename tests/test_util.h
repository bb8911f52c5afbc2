// tests/test_util.h — shared fixtures: the Dolz et al. (2014) example systems and helpers
// to build scenarios and models in code.
#pragma once

#include <Eigen/Dense>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "estimators/estimator.h"
#include "models/link.h"
#include "sim/scenario.h"

namespace ncosim::testing {

inline std::string source_path(const std::string& rel) { return std::string(NCOSIM_SOURCE_DIR) + "/" + rel; }

inline std::string read_text(const std::string& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// Dolz et al. 2014, example 1: A3, Bu, Bw, W and the two sensors.
inline models::LinearPlant dolz_plant(int system = 3) {
  models::LinearPlant p;
  p.A.resize(2, 2);
  if (system == 1) {
    p.A << 0.8821, -0.0351, -0.0351, 0.7347;
  } else if (system == 2) {
    p.A << 0.8373, -0.7207, 0.7207, 0.8373;
  } else {
    p.A << 1.6684, 0.3197, -0.1003, 0.6782;
  }
  p.Bu.resize(2, 1);
  p.Bu << -0.3359, 0.3466;
  p.Bw.resize(2, 2);
  p.Bw << 0.0121, 0.1347, 0.0112, 0.0831;
  p.W.resize(2, 2);
  p.W << 0.2632, -0.0027, -0.0027, 0.2466;
  p.x0 = Eigen::VectorXd::Zero(2);
  return p;
}

// The A3 model with its two sensors behind the Table 1 (A3 column) delay links.
struct DolzModel {
  std::vector<std::unique_ptr<models::Link>> links;
  est::Model model;
};

inline DolzModel dolz_model(const std::vector<std::vector<double>>& pmfs = {{0.3340, 0.3064}, {0.3761, 0.3403}}) {
  DolzModel d;
  d.model.plant = dolz_plant(3);
  const double c[2][2] = {{0.5325, 0.3987}, {0.7258, 0.3584}};
  const double r[2] = {0.0086, 0.0079};
  for (std::size_t i = 0; i < pmfs.size(); ++i) {
    d.links.push_back(std::make_unique<models::DelayPmfLink>(pmfs[i]));
    est::SensorModel s;
    s.spec.name = "y" + std::to_string(i + 1);
    s.spec.C.resize(1, 2);
    s.spec.C << c[i][0], c[i][1];
    s.spec.R = Eigen::MatrixXd::Constant(1, 1, r[i]);
    s.spec.link = static_cast<int>(i);
    s.link = d.links.back().get();
    d.model.sensors.push_back(s);
  }
  return d;
}

// Loads a scenario file (with --set overrides) and returns its single case.
inline std::unique_ptr<sim::Scenario> load_one(const std::string& file, const std::vector<std::string>& sets = {}) {
  auto loaded = sim::load_cases(file, sets);
  return std::move(loaded.cases.front().scenario);
}

}  // namespace ncosim::testing
