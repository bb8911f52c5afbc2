// tests/conformance/fixtures.h — the conformance suite's minimal table of every registered kind
// and its small scenario, shared by conformance_test.cc and allocation_test.cc. A new kind must
// add its minimal table to the maps below, or KindsHaveAConformanceEntry fails.
#pragma once

#include <gtest/gtest.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <utility>
#include <vector>

namespace ncosim::sim::conformance {

inline const std::map<std::string, std::string> kEstimators{
    {"jump", "grouping = \"S3\"\nhistory = 2\nmax_delay = 1"},
    {"kalman_extended", "max_delay = 1"},
    {"open_loop", "max_delay = 1"},
    {"imm", "mode_prior = \"stationary\""},
    {"mode_io", "mode_prior = \"uniform\"\nstartup = \"prior_mean\""},
    {"mode_ss", "mode_prior = \"uniform\""},
    {"kalman_buffer", "buffer = 2"},
    {"static_buffer", "buffer = 2"},
    {"sod_kalman", "W = 0.01\nvirtual_variance_factor = 0.3333"},
    {"sod_jump", "w_rms = 0.1"},
};

// Kinds without max_delay: the misspelt key of the unknown-key test, and its correct spelling.
inline const std::map<std::string, std::pair<std::string, std::string>> kMisspelt{
    {"imm", {"mode_priorr = \"uniform\"", "mode_prior"}},
    {"mode_io", {"mode_priorr = \"uniform\"", "mode_prior"}},
    {"mode_ss", {"mode_priorr = \"uniform\"", "mode_prior"}},
    {"sod_kalman", {"virtual_variance_factr = 0.3", "virtual_variance_factor"}},
    {"sod_jump", {"virtual_nois = \"delta2\"", "virtual_noise"}},
};

// Mode estimators need modes: their scenarios get an [[actuator]] on the same link kind.
inline bool is_mode_kind(const std::string& k) {
  return k == "imm" || k == "mode_io" || k == "mode_ss";
}

inline const std::map<std::string, std::string> kLinks{
    {"delay", "pmf = [0.5, 0.3]"},
    {"bernoulli", "loss = 0.2\ndelay = 1"},
    {"negative_binomial", "successes = 3\np = 0.5\nloss = 0.1"},
    {"arrival_cdf", "cdf = [0.1, 0.5]\ntail = 0.8"},
    {"gilbert_elliott", "p_good_to_bad = 0.1\np_bad_to_good = 0.3"},
    {"markov", "transition = [[0.9, 0.1], [0.5, 0.5]]\nloss = [0.0, 1.0]"},
    {"trace", "file = \"TRACE\""},
    {"sumo_distance", "sender = \"leader\"\nreceiver = \"follower\""},
    {"network", "network = \"bus\"\ndesign_pmf = [0.0, 0.7, 0.2]"},
};

// Network kinds ([[network]] kind): a minimal table each (their nodes at a few metres from the
// sink), run by network_conformance_test.cc with two sensors' links as its nodes.
inline const std::map<std::string, std::string> kNetworks{
    {"csma", "rate = 1e6"},
    {"lr_wpan", "tx_power = 0.0"},
    {"wifi", "standard = \"802.11a\""},
};

inline const std::map<std::string, std::string> kPlants{
    {"lti",
     "A = [[0.8821, -0.0351], [-0.0351, 0.7347]]\nBu = [[-0.3359], [0.3466]]\nW = [[0.01, 0], [0, "
     "0.01]]"},
    {"lti_continuous",
     "Ac = [[-0.1, 1.0], [0.0, -0.3]]\nBc = [[0.0], [1.0]]\nWc = [[0.01, 0], [0, 0.01]]"},
    {"jump_linear",
     "A = [[0.8821, -0.0351], [-0.0351, 0.7347]]\nBu = [[-0.3359], [0.3466]]\nW = [[0.01, 0], [0, "
     "0.01]]\n"
     "transition = [[0.9, 0.1], [0.3, 0.7]]\n[[plant.mode]]\n[[plant.mode]]\nA = [[0.5, 0.0], "
     "[0.1, 0.6]]\n"
     "W = [[0.05, 0], [0, 0.05]]"},
    {"transfer_function", "num = [1.0]\nden = [1.0, 0.5, 0.1]\nW = 0.01"},
    {"sumo_vehicle", "vehicle = \"leader\"\nq = 1.0"},
};

// Kinds that need a [sumo] table (SUMO vehicles): exercised by tests/sumo on a generated road,
// skipped by the generic loops below.
inline bool needs_sumo(const std::string& kind) { return kind.starts_with("sumo_"); }
// Kinds the generic loops skip because their own suite exercises them: the SUMO kinds, and the
// `network` link, a node of a [[network]] simulated by ns-3 (tests/network).
inline bool exercised_elsewhere(const std::string& kind) {
  return needs_sumo(kind) || kind == "network";
}

inline const std::map<std::string, std::string> kInputs{
    {"none", ""},
    {"white", "std = 1.0"},
    {"state_feedback", "K = [[0.1, 0.1]]\nsource = \"plant\""},
    {"relay", "level = 0.5\ndead_zone = 0.2\noutputs = [0]\nsees = \"measured\""},
    {"pi",
     "kp = 0.1\nki = 0.05\nb = 0.7\nu_min = -1.0\nu_max = 1.0\nreference = {kind = \"square\", low "
     "= 0.0, high = 1.0, period = 50.0}"},
};

// Send policies ([[sensor]] policy): the keys each needs on a one-output sensor.
inline const std::map<std::string, std::string> kSendPolicies{
    {"periodic", ""},
    {"send_on_delta", "delta = 0.05"},
};

struct TempDir {
  std::filesystem::path path;
  TempDir() {
    path = std::filesystem::temp_directory_path() /
           ("ncosim_conf_" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()) +
            "_" + std::to_string(reinterpret_cast<std::uintptr_t>(this)));
    std::filesystem::create_directories(path);
  }
  ~TempDir() { std::filesystem::remove_all(path); }
};

// A small scenario: the given plant, input, one link kind for both sensors, and estimators.
inline std::string scenario_text(const std::string& plant_kind, const std::string& input_kind,
                                 const std::string& link_kind,
                                 const std::vector<std::string>& est_kinds,
                                 const std::string& extra_estimator_key = "") {
  std::string s = "[run]\nperiods = 3000\nwarmup = 100\nruns = 3\nseed = 7\n\n";
  s += "[plant]\nkind = \"" + plant_kind + "\"\n" + kPlants.at(plant_kind) + "\n\n";
  s += "[input]\nkind = \"" + input_kind + "\"\n" + kInputs.at(input_kind) + "\n\n";
  s += "[[link]]\nname = \"net\"\nkind = \"" + link_kind + "\"\n" + kLinks.at(link_kind) + "\n\n";
  s += "[[sensor]]\nC = [[1.0, 0.0]]\nR = [[0.01]]\nlink = \"net\"\n\n";
  s += "[[sensor]]\nC = [[0.0, 1.0]]\nR = [[0.01]]\nlink = \"net\"\n\n";
  bool modes = false;
  for (const auto& k : est_kinds) modes = modes || is_mode_kind(k);
  if (modes) s += "[[actuator]]\nlink = \"net\"\non_loss = \"hold\"\n\n";
  for (const auto& k : est_kinds) {
    s += "[[estimator]]\nname = \"" + k + "\"\nkind = \"" + k + "\"\n" + kEstimators.at(k) + "\n" +
         extra_estimator_key + "\n";
  }
  return s;
}

inline std::string write_scenario(const TempDir& dir, const std::string& text) {
  {
    std::ofstream trace(dir.path / "trace.csv");
    trace << "seq,delay\n";
    for (int i = 0; i < 25000; ++i)
      trace << i << "," << (i % 5 == 4 ? "" : std::to_string(i % 2)) << "\n";
  }
  std::string t = text;
  for (std::size_t p; (p = t.find("TRACE")) != std::string::npos;) t.replace(p, 5, "trace.csv");
  const auto file = (dir.path / "s.toml").string();
  std::ofstream(file) << t;
  return file;
}

}  // namespace ncosim::sim::conformance
