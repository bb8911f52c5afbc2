// sumo/mobility.h — SUMO as the mobility source of a scenario ([sumo] table).
// Record and replay: every mobility realisation (SUMO seed) is simulated once, in its own
// worker process (`ncosim sumo-record`, one libsumo simulation per process), and stored as a
// binary trajectory of the vehicles the scenario names, keyed by the content hash of every
// SUMO input file, the step, the horizon, the vehicle list and the seed. Monte Carlo runs
// replay the recordings on every thread (run r uses realisation r mod seeds); no SUMO runs in
// the hot loop. `mode = "live"` steps libsumo in-process instead (one run at a time) and gives
// the same numbers.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "sim/config.h"
#include "sim/mobility.h"
#include "sim/scenario.h"

namespace ncosim::sumo {

// What a worker needs to simulate one realisation.
struct SumoInputs {
  std::vector<std::string> args;   // SUMO options naming the inputs ("-c", cfg) or ("-n", net, "-r", ...)
  std::vector<std::string> files;  // every input file (hashed)
  std::int64_t step_ms = 100;
};

// One realisation: frames x vehicles states; frame j is the state after j SUMO steps.
struct Recording {
  std::int64_t step_ms = 0;
  std::int64_t frames = 0;
  std::vector<std::string> vehicles;
  std::vector<sim::VehicleState> states;  // frame-major
  const sim::VehicleState& at(std::int64_t frame, int v) const {
    return states[static_cast<std::size_t>(frame * static_cast<std::int64_t>(vehicles.size()) + v)];
  }
};

void write_recording(const std::string& path, const Recording& r);
Recording read_recording(const std::string& path);  // throws std::runtime_error

// Simulates one realisation in this process with libsumo (throws std::runtime_error with
// SUMO's message on failure). The worker subcommand calls this.
Recording record(const SumoInputs& in, std::uint64_t seed, std::int64_t frames,
                 const std::vector<std::string>& vehicles);

// libsumo stepped live for one run (one at a time per process).
std::unique_ptr<sim::MobilityRun> start_live(const SumoInputs& in, std::uint64_t seed,
                                             const std::vector<std::string>& vehicles);

class Mobility final : public sim::MobilitySource {
 public:
  Mobility(const sim::Table& t, const sim::RunSettings& run, const std::string& dir);
  int vehicle(const sim::Table& t, std::string_view key) override;
  void prepare() override;
  std::unique_ptr<sim::MobilityRun> start(std::uint64_t run) const override;
  bool single_threaded() const override { return live_; }

  const std::vector<Recording>& recordings() const { return recordings_; }
  const std::vector<std::string>& vehicles() const { return vehicles_; }
  std::int64_t step_ms() const { return inputs_.step_ms; }
  // Realisations simulated / reused by prepare() (for the log line and tests).
  int recorded() const { return recorded_; }
  int reused() const { return reused_; }

 private:
  std::string key_for(std::uint64_t seed) const;
  std::string file_, config_key_;
  int line_ = 0;
  SumoInputs inputs_;
  std::uint64_t first_seed_ = 1;
  int seeds_ = 1;
  bool live_ = false;
  std::string cache_dir_;
  std::int64_t horizon_ns_ = 0;
  std::int64_t frames_ = 0;
  std::vector<std::string> vehicles_;
  struct Origin {
    std::string file, path;
    int line;
  };
  std::vector<Origin> origins_;  // where each vehicle was first named
  std::vector<Recording> recordings_;
  int recorded_ = 0, reused_ = 0;
};

// Where the worker processes come from: the ncosim executable (set by the CLI). When empty
// (library use, tests), realisations are simulated in this process, one after the other.
void set_worker_executable(const std::string& path);
// `ncosim sumo-record` (hidden): argv after the subcommand name. Returns the exit code.
int worker_main(const std::vector<std::string>& args);

// Cache folder: [sumo] cache, else $NCOSIM_SUMO_CACHE, else $XDG_CACHE_HOME/ncosim/sumo,
// else $HOME/.cache/ncosim/sumo.
std::string default_cache_dir();

}  // namespace ncosim::sumo
