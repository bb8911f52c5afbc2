// models/mobility.h — the kernel's view of an external mobility source (SUMO, see sumo/): the
// state of the vehicles a scenario names, advanced by the kernel's clock. Header only, so the
// kernel builds without SUMO; the sumo/ component implements it (replay of recorded
// trajectories, or libsumo stepped live in a worker process).
#pragma once

#include <cstdint>
#include <memory>
#include <string_view>
#include <vector>

#include "config/config.h"
#include "kernel/time.h"

namespace ncosim::models {

struct VehicleState {
  double x = 0.0, y = 0.0;  // network coordinates (m)
  double pos = 0.0;         // distance driven along the route since departure (m)
  double speed = 0.0;       // m/s
  double accel = 0.0;       // m/s^2
  bool present = false;     // in the network at this time (departed, not arrived)
};

// One run's mobility: advance(t) moves to the last mobility step at or before t (never
// beyond: the kernel owns the clock); vehicle(i) is the state of the i-th named vehicle then.
class MobilityRun {
 public:
  virtual ~MobilityRun() = default;
  virtual void advance(kernel::SimTime t) = 0;
  virtual const VehicleState& vehicle(int index) const = 0;
};

// A scenario's mobility source: one MobilityRun per Monte Carlo run.
class MobilitySource {
 public:
  virtual ~MobilitySource() = default;
  virtual std::unique_ptr<MobilityRun> start(std::uint64_t run) const = 0;
  // True when runs must not run concurrently (one libsumo simulation per process).
  virtual bool single_threaded() const = 0;
  // Scenario reading: the index of the vehicle named by t[key] (recorded from then on).
  virtual int vehicle(const config::Table& t, std::string_view key) = 0;
  // Scenario reading: the indices of every vehicle of the traffic, named as a group by t[key]
  // (e.g. every vehicle beacons); a vehicle of the group that never drives during the horizon is
  // no error. Throws ScenarioError at t[key] when the traffic's vehicles are not known by id.
  virtual std::vector<int> every_vehicle(const config::Table& t, std::string_view key) = 0;
  // Records (or reuses) every realisation once all readers have named their vehicles.
  // Throws ScenarioError (bad input, SUMO errors).
  virtual void prepare() = 0;
};

}  // namespace ncosim::models
