// sumo/traffic.h — SUMO traffic as the mobility source of a scenario ([sumo] table).
// Record and replay: every mobility realisation (SUMO seed) is simulated once by the `sumo`
// binary itself, one process per realisation (at most one per core at a time), writing FCD
// output (x, y, speed, acceleration, odometer at 40 decimals) for the named vehicles only; the
// FCD file is read by a strict reader (parse_fcd) into a binary trajectory, keyed by the content
// hash of every SUMO input file, the step, the horizon and the seed (the traffic: one recording
// holds the vehicles of every case of a scenario, see announce_vehicles in sumo.h), and the
// FCD file is deleted. Monte Carlo runs replay the recordings on every thread (run r uses
// realisation r mod seeds); no SUMO runs in the hot loop. `mode = "live"` steps libsumo in a
// worker process per run (`ncosim sumo-live`, which dlopens the libsumo module) over a socket
// with a small binary protocol; the main process never loads libsumo. Live gives the same
// numbers as replay: the FCD text round-trips every value bit for bit (checked by the tests)
// except values whose magnitude is below ~1e-23, which 40 fixed decimals cannot carry to 17
// significant digits (none occurred in the test road or the benchmark grid: bench/README.md).
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "config/config.h"
#include "config/run_settings.h"
#include "models/mobility.h"

namespace ncosim::sumo {

// What a worker needs to simulate one realisation.
struct SumoInputs {
  std::vector<std::string>
      args;  // SUMO options naming the inputs ("-c", cfg) or ("-n", net, "-r", ...)
  std::vector<std::string> files;  // every input file (hashed)
  std::int64_t step_ms = 100;
};

// One realisation: frames x vehicles states; frame j is the state after j SUMO steps.
struct Recording {
  std::int64_t step_ms = 0;
  std::int64_t frames = 0;
  std::vector<std::string> vehicles;
  std::vector<models::VehicleState> states;  // frame-major
  const models::VehicleState& at(std::int64_t frame, int v) const {
    return states[static_cast<std::size_t>(frame * static_cast<std::int64_t>(vehicles.size()) + v)];
  }
};

// The SUMO options of every simulation (recording and live): the inputs, quiet, no XML schema
// validation, the seed, the step and begin 0. Header-only: the libsumo module uses it too.
inline std::vector<std::string> sumo_arguments(const SumoInputs& in, std::uint64_t seed) {
  std::vector<std::string> a = in.args;
  for (const char* o : {"--no-step-log", "--no-warnings", "--duration-log.disable"})
    a.insert(a.end(), {o, "true"});
  for (const char* o : {"--xml-validation", "--xml-validation.net", "--xml-validation.routes"}) {
    a.insert(a.end(), {o, "never"});
  }
  std::string ms = std::to_string(in.step_ms % 1000);
  ms.insert(0, 3 - ms.size(), '0');
  a.insert(a.end(), {"--seed", std::to_string(seed), "--step-length",
                     std::to_string(in.step_ms / 1000) + "." + ms, "--begin", "0"});
  return a;
}

void write_recording(const std::string& path, const Recording& r);
Recording read_recording(const std::string& path);  // throws std::runtime_error

// Simulates one realisation with the `sumo` binary (FCD output, parsed by parse_fcd; throws
// std::runtime_error with SUMO's message on failure).
Recording record(const SumoInputs& in, std::uint64_t seed, std::int64_t frames,
                 const std::vector<std::string>& vehicles);

// Records realisation `seed` of the traffic into the recording file `path`.
struct RecordingJob {
  std::uint64_t seed;
  std::string path;
};
// Runs the jobs with the `sumo` binary, one process per realisation and at most one per core at
// a time, writing the recordings of `vehicles`; throws std::runtime_error with the first failure
// (after waiting for every process started).
void record_all(const SumoInputs& in, std::int64_t frames, const std::vector<std::string>& vehicles,
                const std::vector<RecordingJob>& jobs);

// Reads SUMO FCD output (the elements and attributes record() asks for, nothing else: any
// other content is an error naming the byte offset). Frame f (state after f steps) is
// <timestep time="(f-1)*step">; a vehicle absent from a timestep is present = false and keeps
// its last state (zeros before departure). Timesteps past the horizon are ignored.
Recording parse_fcd(const std::string& path, std::int64_t step_ms, std::int64_t frames,
                    const std::vector<std::string>& vehicles);

// The `sumo` binary: $NCOSIM_SUMO_BINARY (only it, when set), else `sumo` on PATH, else
// $SUMO_HOME/bin/sumo; throws std::runtime_error when none is executable.
std::string sumo_binary();

// libsumo stepped live for one run in a worker process (`ncosim sumo-live`, the executable set
// by set_worker_executable; throws std::runtime_error without one).
std::unique_ptr<models::MobilityRun> start_live(const SumoInputs& in, std::uint64_t seed,
                                                const std::vector<std::string>& vehicles);

class Mobility final : public models::MobilitySource {
 public:
  Mobility(const config::Table& t, const config::RunSettings& run, const std::string& dir);
  int vehicle(const config::Table& t, std::string_view key) override;
  std::vector<int> every_vehicle(const config::Table& t, std::string_view key) override;
  void prepare() override;
  std::unique_ptr<models::MobilityRun> start(std::uint64_t run) const override;
  bool single_threaded() const override { return live_; }

  const std::vector<Recording>& recordings() const { return recordings_; }
  const std::vector<std::string>& vehicles() const { return vehicles_; }
  std::int64_t step_ms() const { return inputs_.step_ms; }
  // Realisations simulated / reused by prepare() (for the log line and tests).
  int recorded() const { return recorded_; }
  int reused() const { return reused_; }
  // The traffic's identity: the content of every SUMO input file, the step and the horizon (not
  // the vehicles a case reads, not the seed). Recordings are keyed by it and the seed.
  std::string traffic_key() const;

 private:
  std::string key_for(std::uint64_t seed) const;
  // Throws the ScenarioError `why` at the [sumo] table's input key.
  [[noreturn]] void fail(const std::string& why) const;
  // Reads job j's recording into recordings_ (this case's vehicles only) and checks it.
  void load(const RecordingJob& j);
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
    bool may_be_absent = false;  // named in a group (every_vehicle): may never drive
  };
  std::vector<Origin> origins_;  // where each vehicle was first named
  std::vector<Recording> recordings_;
  int recorded_ = 0, reused_ = 0;
};

// The live worker executable: the ncosim executable (set by the CLI; tests set it too).
void set_worker_executable(const std::string& path);
// `ncosim sumo-live` (hidden): argv after the subcommand name; talks on file descriptor 3.
// Returns the exit code.
int live_worker_main(const std::vector<std::string>& args);

// Cache folder: [sumo] cache, else $NCOSIM_SUMO_CACHE, else $XDG_CACHE_HOME/ncosim/sumo,
// else $HOME/.cache/ncosim/sumo.
std::string default_cache_dir();

}  // namespace ncosim::sumo
