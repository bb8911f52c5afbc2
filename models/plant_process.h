// models/plant_process.h — the true plant of one run: a per-run behaviour object that steps the
// state. Which process a plant kind runs is part of what its reader returns
// (LinearPlant::process, empty = the linear process below), so a new plant kind brings its own
// process with it and the run loop (sim/run/run.cc) never tests the kind. Built in:
// - linear (lti, lti_continuous, transfer_function): x[k] = A x[k-1] + Bu u[k-1] + Bw w[k-1]
//   (+ the known re-centring), w = W^1/2 N(0, I) plus the deterministic disturbance;
// - jump_linear: the same with the mode m = theta[k-1] of a Markov chain choosing A, Bu, Bw, W;
// - vehicle (sumo_vehicle): x = the longitudinal motion of a vehicle of the mobility source.
#pragma once

#include <Eigen/Dense>
#include <cstdint>
#include <functional>
#include <memory>

#include "kernel/rng.h"
#include "models/mobility.h"
#include "models/plant.h"

namespace ncosim::models {

// What a run hands its plant process.
struct PlantRun {
  std::uint64_t seed = 0, run = 0;           // for the plant's random streams
  MobilityRun* mobility = nullptr;           // the run's mobility ([sumo]; nullptr without)
  int vehicle = -1;                          // the plant vehicle's index in the mobility
  const Disturbance* disturbance = nullptr;  // deterministic part of w ([plant.disturbance])
  bool recentre = false;                     // simulate in re-centred coordinates
};

// The signals a plant step writes (owned by the run, sized by it: n, nu).
struct PlantSignals {
  Eigen::VectorXd x;      // x[k]
  Eigen::VectorXd drive;  // the applied known part of x[k] - A_m x[k-1] - Bw_m w: Bu_m u + recentre
  Eigen::VectorXd recentre;  // the re-centring term -A x[k-1] (zero without re-centring)
  int mode = -1;             // theta[k-1] of a jump plant (-1: none)
};

class PlantProcess {
 public:
  virtual ~PlantProcess() = default;
  // Period k: k = 0 sets x[0] (already x0 for simulated plants); k >= 1 steps x[k-1] -> x[k]
  // with the input u_applied that acted during period k - 1. Returns true when x changed (the
  // true-state history then shifts).
  virtual bool step(std::int64_t k, const Eigen::VectorXd& u_applied, PlantSignals& s) = 0;
  // False when the applied drive is not the nominal Bu u + recentre (a jump plant's modes): the
  // estimators then get the nominal one, computed from what was sent.
  virtual bool drive_is_nominal() const { return true; }
};

std::unique_ptr<PlantProcess> linear_process(const LinearPlant& plant, const PlantRun& run);
std::unique_ptr<PlantProcess> jump_linear_process(const LinearPlant& plant, const PlantRun& run);
std::unique_ptr<PlantProcess> vehicle_process(const LinearPlant& plant, const PlantRun& run);

// The plant's own process (LinearPlant::process), or the linear one.
std::unique_ptr<PlantProcess> make_plant_process(const LinearPlant& plant, const PlantRun& run);

}  // namespace ncosim::models
