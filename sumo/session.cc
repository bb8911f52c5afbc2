// sumo/session.cc — the only file that calls libsumo: one simulation loaded, stepped and read.
// libsumo holds one simulation per process: a Session must not overlap another in time.
// Built as a loadable module (libncosim_sumo_session.so), opened with dlopen only by the
// processes that run SUMO (workers, live mode): libsumocpp pulls ~220 shared libraries, which
// would otherwise add ~0.4 s to the start of every ncosim command.
#include <fmt/format.h>
#include <libsumo/libsumo.h>

#include <cstdlib>
#include <stdexcept>
#include <unordered_map>

#include "sumo/mobility.h"

namespace ncosim::sumo {

namespace {

std::string ms_to_seconds(std::int64_t ms) { return fmt::format("{}.{:03}", ms / 1000, ms % 1000); }

class Session {
 public:
  Session(const SumoInputs& in, std::uint64_t seed, const std::vector<std::string>& vehicles)
      : states_(vehicles.size()) {
    // Without SUMO_HOME, SUMO fetches XML schemas and rejects files written by its own tools.
    ::setenv("SUMO_HOME", "/usr/share/sumo", 0);
    std::vector<std::string> args = in.args;
    for (const char* a : {"--no-step-log", "--no-warnings", "--duration-log.disable"}) {
      args.emplace_back(a);
      args.emplace_back("true");
    }
    for (const char* a : {"--xml-validation", "--xml-validation.net", "--xml-validation.routes"}) {
      args.emplace_back(a);
      args.emplace_back("never");
    }
    args.insert(args.end(), {"--seed", std::to_string(seed), "--step-length", ms_to_seconds(in.step_ms),
                             "--begin", "0"});
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
        if (auto it = index_.find(id); it != index_.end()) states_[static_cast<std::size_t>(it->second)].present = true;
      }
      for (const auto& id : libsumo::Simulation::getArrivedIDList()) {
        if (auto it = index_.find(id); it != index_.end()) states_[static_cast<std::size_t>(it->second)].present = false;
      }
      for (const auto& [id, i] : index_) {
        sim::VehicleState& s = states_[static_cast<std::size_t>(i)];
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
  const sim::VehicleState& state(int i) const { return states_[static_cast<std::size_t>(i)]; }
  const std::vector<sim::VehicleState>& states() const { return states_; }

 private:
  std::unordered_map<std::string, int> index_;
  std::vector<sim::VehicleState> states_;
  bool open_ = false;
};

class LiveRun final : public sim::MobilityRun {
 public:
  LiveRun(const SumoInputs& in, std::uint64_t seed, const std::vector<std::string>& vehicles)
      : session_(in, seed, vehicles), step_ns_(in.step_ms * 1'000'000) {}
  void advance(sim::SimTime t) override {
    const std::int64_t target = t / step_ns_;
    while (frame_ < target) {
      session_.step();
      ++frame_;
    }
  }
  const sim::VehicleState& vehicle(int index) const override { return session_.state(index); }

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
void ncosim_sumo_record(const ncosim::sumo::SumoInputs* in, std::uint64_t seed, std::int64_t frames,
                        const std::vector<std::string>* vehicles, ncosim::sumo::Recording* out);
ncosim::sim::MobilityRun* ncosim_sumo_start_live(const ncosim::sumo::SumoInputs* in, std::uint64_t seed,
                                                const std::vector<std::string>* vehicles);
}

void ncosim_sumo_record(const ncosim::sumo::SumoInputs* in_ptr, std::uint64_t seed, std::int64_t frames,
                        const std::vector<std::string>* vehicles_ptr, ncosim::sumo::Recording* out) {
  using namespace ncosim::sumo;
  const SumoInputs& in = *in_ptr;
  const std::vector<std::string>& vehicles = *vehicles_ptr;
  Recording& r = *out;
  r.step_ms = in.step_ms;
  r.frames = frames;
  r.vehicles = vehicles;
  r.states.reserve(static_cast<std::size_t>(frames) * vehicles.size());
  Session s(in, seed, vehicles);
  for (std::int64_t j = 0; j < frames; ++j) {
    if (j > 0) s.step();
    r.states.insert(r.states.end(), s.states().begin(), s.states().end());
  }
}

ncosim::sim::MobilityRun* ncosim_sumo_start_live(const ncosim::sumo::SumoInputs* in, std::uint64_t seed,
                                                const std::vector<std::string>* vehicles) {
  return new ncosim::sumo::LiveRun(*in, seed, *vehicles);
}
