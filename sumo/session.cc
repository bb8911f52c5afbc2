// sumo/session.cc — the only file that calls libsumo: one simulation loaded, stepped and read
// (live mode). libsumo holds one simulation per process: a Session must not overlap another.
// Built as a loadable module (libncosim_sumo_session.so), opened with dlopen only by the live
// worker process (`ncosim sumo-live`): libsumocpp pulls ~220 shared libraries, which would
// otherwise add ~0.1-0.4 s to the start of every ncosim command. Recording uses the `sumo`
// binary's FCD output instead (mobility.cc), which reads the same values.
#include <fmt/format.h>
#include <libsumo/libsumo.h>

#include <cstdlib>
#include <stdexcept>
#include <unordered_map>

#include "sumo/traffic.h"

namespace ncosim::sumo {

namespace {

class Session {
 public:
  Session(const SumoInputs& in, std::uint64_t seed, const std::vector<std::string>& vehicles)
      : states_(vehicles.size()) {
    // Without SUMO_HOME, SUMO fetches XML schemas and rejects files written by its own tools.
    ::setenv("SUMO_HOME", "/usr/share/sumo", 0);
    const std::vector<std::string> args = sumo_arguments(in, seed);
    for (std::size_t i = 0; i < vehicles.size(); ++i) index_[vehicles[i]] = static_cast<int>(i);
    try {
      libsumo::Simulation::load(args);
    } catch (const std::exception& e) {
      throw std::runtime_error(e.what());
    }
    open_ = true;
  }
  ~Session() {
    if (open_) {
      try {
        libsumo::Simulation::close();
      } catch (...) {
      }
    }
  }
  Session(const Session&) = delete;
  Session& operator=(const Session&) = delete;

  void step() {
    try {
      libsumo::Simulation::step();
      for (const auto& id : libsumo::Simulation::getDepartedIDList()) {
        if (auto it = index_.find(id); it != index_.end())
          states_[static_cast<std::size_t>(it->second)].present = true;
      }
      // A teleporting vehicle is off the road: absent (keeping its last state) until the
      // teleport ends, exactly as SUMO's FCD output, which the recordings are made from, leaves
      // it out.
      for (const auto& id : libsumo::Simulation::getStartingTeleportIDList()) {
        if (auto it = index_.find(id); it != index_.end())
          states_[static_cast<std::size_t>(it->second)].present = false;
      }
      for (const auto& id : libsumo::Simulation::getEndingTeleportIDList()) {
        if (auto it = index_.find(id); it != index_.end())
          states_[static_cast<std::size_t>(it->second)].present = true;
      }
      for (const auto& id : libsumo::Simulation::getArrivedIDList()) {
        if (auto it = index_.find(id); it != index_.end())
          states_[static_cast<std::size_t>(it->second)].present = false;
      }
      for (const auto& [id, i] : index_) {
        models::VehicleState& s = states_[static_cast<std::size_t>(i)];
        if (!s.present) continue;  // before departure: zeros; after arrival: the last state
        const auto p = libsumo::Vehicle::getPosition(id);
        s.x = p.x;
        s.y = p.y;
        s.pos = libsumo::Vehicle::getDistance(id);
        s.speed = libsumo::Vehicle::getSpeed(id);
        s.accel = libsumo::Vehicle::getAcceleration(id);
      }
    } catch (const std::exception& e) {
      throw std::runtime_error(e.what());
    }
  }
  const models::VehicleState& state(int i) const { return states_[static_cast<std::size_t>(i)]; }
  const std::vector<models::VehicleState>& states() const { return states_; }

 private:
  std::unordered_map<std::string, int> index_;
  std::vector<models::VehicleState> states_;
  bool open_ = false;
};

class LiveRun final : public models::MobilityRun {
 public:
  LiveRun(const SumoInputs& in, std::uint64_t seed, const std::vector<std::string>& vehicles)
      : session_(in, seed, vehicles), step_ns_(in.step_ms * 1'000'000) {}
  void advance(kernel::SimTime t) override {
    const std::int64_t target = t / step_ns_;
    while (frame_ < target) {
      session_.step();
      ++frame_;
    }
  }
  const models::VehicleState& vehicle(int index) const override { return session_.state(index); }

 private:
  Session session_;
  std::int64_t step_ns_;
  std::int64_t frame_ = 0;
};

}  // namespace

}  // namespace ncosim::sumo

// The module's entry points (looked up by name with dlsym; C++ exceptions cross the boundary:
// same compiler and runtime).
extern "C" {
ncosim::models::MobilityRun* ncosim_sumo_start_live(const ncosim::sumo::SumoInputs* in,
                                                    std::uint64_t seed,
                                                    const std::vector<std::string>* vehicles);
}

ncosim::models::MobilityRun* ncosim_sumo_start_live(const ncosim::sumo::SumoInputs* in,
                                                    std::uint64_t seed,
                                                    const std::vector<std::string>* vehicles) {
  return new ncosim::sumo::LiveRun(*in, seed, *vehicles);
}
