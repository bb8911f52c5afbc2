// estimators/buffer_common.h — what kalman_buffer and static_buffer share: the `buffer` key,
// the arrival probabilities lambda_h = P[delay <= h] of each sensor, the plant in the form of
// estimators/design/buffer_design.h, and the critical probability fields of design.json.
#pragma once

#include <fmt/format.h>

#include <Eigen/Eigenvalues>
#include <cmath>
#include <map>
#include <mutex>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "estimators/design/buffer_design.h"
#include "estimators/estimator.h"

namespace ncosim::est {

// `buffer` = N >= 1: samples with delay 0 .. N-1 are used, older ones discarded. `max_delay`
// = N - 1 is accepted instead (the key of the delay-extended estimators); not both. With
// xhat0 and P0 these are the keys of both kinds.
inline const config::Keys& buffer_keys() {
  using config::Key;
  static const config::Keys keys =
      config::Keys{
          Key::integer("buffer").range(1, 1000).or_default(1).unit("periods").help(
              "N: samples with delay 0 .. N - 1 are used"),
          Key::integer("max_delay")
              .range(0, 999)
              .optional("none")
              .unit("periods")
              .help("alternative to buffer: N = max_delay + 1 (not both)"),
      } +
      initial_keys();
  return keys;
}

inline int read_buffer(const config::KeyReader& r) {
  if (r.has("max_delay")) {
    if (r.has("buffer"))
      r.fail("max_delay", "expected either buffer or max_delay (= buffer - 1), got both");
    return static_cast<int>(*r.opt_integer("max_delay")) + 1;
  }
  return static_cast<int>(r.integer("buffer"));
}

// lambda[i][h] = P[a sample of sensor i arrives with delay <= h], h = 0 .. N-1.
inline std::vector<std::vector<double>> arrival_probabilities(const Model& model, int N) {
  std::vector<std::vector<double>> out;
  for (const auto& s : model.sensors) {
    const auto pmf = s.delay_pmf(N - 1);
    std::vector<double> cdf(pmf.size());
    double acc = 0.0;
    for (std::size_t h = 0; h < pmf.size(); ++h) cdf[h] = std::min(1.0, acc += pmf[h]);
    out.push_back(std::move(cdf));
  }
  return out;
}

inline buffer::Plant buffer_plant(const Model& model) {
  buffer::Plant p;
  p.A = model.plant.A;
  p.Q = model.plant.Bw * model.plant.W * model.plant.Bw.transpose();
  for (const auto& s : model.sensors) {
    p.C.push_back(s.spec.C);
    p.R.push_back(s.spec.R);
  }
  return p;
}

// design.json fields of the critical probability (lambda_c of the sensors arriving together), by
// the SDP of eq. (37) and by bisection on the fixed point of Phi_lambda. `critical_probability`
// is the SDP value (the bisection value if the SDP failed). Both are cached per plant for the
// process: a sweep over N designs the same plant many times.
inline void report_critical_probability(const buffer::Plant& p, nlohmann::json& extra) {
  struct Both {
    buffer::CriticalProbability sdp, bisection;
  };
  static std::mutex mutex;
  static std::map<std::string, Both> cache;
  std::string key;
  auto add = [&key](const Eigen::MatrixXd& m) {
    key += std::to_string(m.rows()) + "x" + std::to_string(m.cols()) + ":";
    key.append(reinterpret_cast<const char*>(m.data()),
               static_cast<std::size_t>(m.size()) * sizeof(double));
  };
  add(p.A);
  for (std::size_t i = 0; i < p.C.size(); ++i) {
    add(p.C[i]);
    add(p.R[i]);
  }
  Both both;
  {
    std::lock_guard<std::mutex> lock(mutex);
    auto it = cache.find(key);
    if (it == cache.end()) {
      it = cache
               .emplace(key, Both{buffer::critical_probability_sdp(p),
                                  buffer::critical_probability_bisection(p)})
               .first;
    }
    both = it->second;
  }
  const bool sdp_ok = std::isfinite(both.sdp.value);
  extra["critical_probability"] = sdp_ok ? both.sdp.value : both.bisection.value;
  extra["critical_probability_method"] = sdp_ok ? "sdp" : "bisection";
  extra["critical_probability_sdp"] =
      sdp_ok ? nlohmann::json(both.sdp.value) : nlohmann::json(nullptr);
  extra["critical_probability_sdp_seconds"] = both.sdp.seconds;
  extra["critical_probability_bisection"] = both.bisection.value;
  extra["critical_probability_bisection_seconds"] = both.bisection.seconds;
  extra["critical_probability_bounds"] = {both.bisection.lower_bound, both.bisection.upper_bound};
  extra["detectable"] = both.bisection.detectable;
}

// Cost estimates of the two buffer kinds (DesignCost, estimator.h), from the designs of
// estimators/design/buffer_design.cc. The dominant part is the second-moment operator of a gain,
// an n^2 x n^2 matrix built with one dense product per sensor, then an eigenvalue solve (about 15
// products' work) and an LU solve: l_fixed_point, (2 sensors + 16) n^6 flops and about 8 such
// matrices alive at once. kBufferMomentSolves is how many of those one Riccati fixed point takes
// when it exists (value iterations until a gain stabilises, then policy iterations). The critical
// probability (unstable plants only) bisects 24 times to 1e-7; about half the steps fall below
// lambda_c, where the value iteration runs until the covariance blows up or 20000 iterations,
// with a moment operator every 4th: kBufferBisectionSolves in all. Calibrated by
// tests/costs/cost_test.cc (bench/README.md, "Design cost estimates").
inline constexpr double kBufferMomentSolves = 8.0;
inline constexpr double kBufferBisectionSolves = 12.0 * 5000.0;

inline double moment_solve_flops(double n, double sensors) {
  const double m = n * n;
  return (2.0 * sensors + 16.0) * m * m * m;
}

// True when the plant is open-loop stable (spectral radius of A below 1): the critical
// probability is then 0 without a bisection. Large plants are assumed unstable (an upper bound).
inline bool buffer_plant_stable(const Model& model) {
  const auto& A = model.plant.A;
  if (A.rows() == 0) return true;
  if (A.rows() > 400 || !A.allFinite()) return false;
  return A.eigenvalues().cwiseAbs().maxCoeff() < 1.0;
}

// The critical probability of design.json (both kinds): nothing for a stable plant, else the
// bisection's fixed points on the plant with its sensors compressed to one. The SDP's LMIs are
// estimated and limited by the LMI layer when they are built.
inline DesignCost critical_probability_cost(const Model& model, bool stable) {
  const double n = static_cast<double>(model.plant.n());
  if (stable || model.sensors.empty()) return {};
  const double m = n * n;
  return {8.0 * 8.0 * m * m, kBufferBisectionSolves * moment_solve_flops(n, 1.0), ""};
}

// The buffer N of `raw` (buffer, or max_delay + 1), as read_buffer reads it.
inline double peek_buffer(const toml::table& raw) {
  const config::Keys& keys = buffer_keys();
  if (raw.get("max_delay") != nullptr)
    return static_cast<double>(peek_integer(raw, keys.at("max_delay")) + 1);
  return static_cast<double>(peek_integer(raw, keys.at("buffer")));
}

inline std::string moment_driver(const std::string& driver, double n) {
  return fmt::format("{} (the second-moment operator is {:.0f} x {:.0f})", driver, n * n, n * n);
}

}  // namespace ncosim::est
