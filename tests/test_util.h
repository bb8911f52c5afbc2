// tests/test_util.h — shared fixtures: the Dolz et al. (2014) example systems and helpers
// to build scenarios and models in code.
#pragma once

#include <sys/wait.h>

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "estimators/estimator.h"
#include "models/link.h"
#include "sim/scenario/scenario.h"

namespace ncosim::testing {

inline std::string source_path(const std::string& rel) {
  return std::string(NCOSIM_SOURCE_DIR) + "/" + rel;
}

inline std::string read_text(const std::string& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// A shell command's exit status (-1 when it did not exit normally) and its stdout and stderr,
// interleaved.
struct CommandOutcome {
  int code = -1;
  std::string output;
};
inline CommandOutcome run_shell(const std::string& cmd) {
  CommandOutcome o;
  FILE* pipe = ::popen((cmd + " 2>&1").c_str(), "r");
  if (pipe == nullptr) return o;
  std::array<char, 4096> buf{};
  std::size_t n = 0;
  while ((n = std::fread(buf.data(), 1, buf.size(), pipe)) > 0) o.output.append(buf.data(), n);
  const int status = ::pclose(pipe);
  o.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return o;
}

// `s` in single quotes for the shell (an embedded ' becomes '\'').
inline std::string shell_quote(const std::string& s) {
  std::string out = "'";
  for (char c : s) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return out + "'";
}

#ifdef NCOSIM_BINARY
// The shell command running the ncosim executable with `args`, each quoted.
inline std::string ncosim_command(const std::vector<std::string>& args) {
  std::string cmd = shell_quote(NCOSIM_BINARY);
  for (const auto& a : args) cmd += " " + shell_quote(a);
  return cmd;
}

// Runs the ncosim executable with `args`: its exit status and its stdout + stderr.
inline CommandOutcome run_ncosim(const std::vector<std::string>& args) {
  return run_shell(ncosim_command(args));
}
#endif

// `text` split at newlines (no line ends kept).
inline std::vector<std::string> split_lines(const std::string& text) {
  std::vector<std::string> out;
  std::istringstream in(text);
  for (std::string l; std::getline(in, l);) out.push_back(l);
  return out;
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

inline DolzModel dolz_model(const std::vector<std::vector<double>>& pmfs = {{0.3340, 0.3064},
                                                                            {0.3761, 0.3403}}) {
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
inline std::unique_ptr<sim::Scenario> load_one(const std::string& file,
                                               const std::vector<std::string>& sets = {}) {
  auto loaded = sim::load_cases(file, sets);
  return std::move(loaded.cases.front().scenario);
}

// The peer system of kf_intermittent_filterpy.csv (tests/data/peers/README.md): A = [[1.25, 1],
// [0, 1.1]], Q = 0.2 I, C = [1 0], R = 0.5, no input.
inline est::Model kf_peer_model() {
  est::Model model;
  model.plant.A.resize(2, 2);
  model.plant.A << 1.25, 1, 0, 1.1;
  model.plant.Bu = Eigen::MatrixXd::Zero(2, 0);
  model.plant.Bw = Eigen::MatrixXd::Identity(2, 2);
  model.plant.W = 0.2 * Eigen::MatrixXd::Identity(2, 2);
  model.plant.x0 = Eigen::VectorXd::Zero(2);
  est::SensorModel s;
  s.spec.C = Eigen::MatrixXd(1, 2);
  s.spec.C << 1, 0;
  s.spec.R = Eigen::MatrixXd::Constant(1, 1, 0.5);
  model.sensors.push_back(s);
  return model;
}

// Replays the peer vectors into `kf` (built on kf_peer_model() with P0 = I): row k (filterpy
// 1.4.5: the posterior after predict + (update if gamma) of step k from xhat0 = 0, P0 = I) is
// our period k + 1. Each of x0, x1, P00, P01, P11 is compared relative to its vector's largest
// entry (the unstable peer run reaches 1e48, and x1's update uses the innovation z - x0, whose
// rounding error is eps |x0|). Returns the rows read (-1: file missing or malformed) and the
// worst relative deviation with where it occurred.
struct PeerReplay {
  int rows = -1;
  double worst = 0.0;
  std::string where;
};
inline PeerReplay replay_kf_peer(est::Estimator& kf) {
  PeerReplay r;
  std::ifstream in(source_path("tests/data/peers/kf_intermittent_filterpy.csv"));
  if (!in) return r;
  const Eigen::VectorXd u0(0), drive = Eigen::VectorXd::Zero(2);
  kf.on_period(0, est::PeriodInput{u0, drive});
  std::string line;
  std::getline(in, line);  // header
  r.rows = 0;
  while (std::getline(in, line)) {
    std::stringstream ss(line);
    std::vector<double> v;
    for (std::string cell; std::getline(ss, cell, ',');) v.push_back(std::stod(cell));
    if (v.size() != 8U) return PeerReplay{};
    const std::int64_t k = static_cast<std::int64_t>(v[0]) + 1;
    if (v[1] == 1.0) {
      est::Packet p;
      p.sensor = 0;
      p.send_period = k;
      p.count = 1;
      p.stamps = {k};
      p.values = Eigen::VectorXd::Constant(1, v[2]);
      kf.on_packet(p, k);
    }
    kf.on_period(k, est::PeriodInput{u0, drive});
    const Eigen::VectorXd x = kf.state();
    const Eigen::MatrixXd& P = *kf.covariance();
    const double xs = std::max({1.0, std::abs(v[3]), std::abs(v[4])});
    const double ps = std::max({1.0, std::abs(v[5]), std::abs(v[6]), std::abs(v[7])});
    const double got[5] = {x(0), x(1), P(0, 0), P(0, 1), P(1, 1)};
    for (int q = 0; q < 5; ++q) {
      const double err = std::abs(got[q] - v[3 + q]) / (q < 2 ? xs : ps);
      if (!(err <= r.worst)) {  // NaN counts as worst
        r.worst = std::isnan(err) ? std::numeric_limits<double>::infinity() : err;
        r.where = "step " + std::to_string(static_cast<long long>(v[0])) + " quantity " +
                  std::to_string(q) + ": " + std::to_string(got[q]) + " vs " +
                  std::to_string(v[3 + q]);
      }
    }
    ++r.rows;
  }
  return r;
}

}  // namespace ncosim::testing
