// network/worker.h — worker processes for the engines whose runs each need a process of their own
// (NetworkEngine::needs_own_process: ns-3 has one simulator per process and keeps state across
// its simulations). Nothing is ever forked from the caller's process, which may run threads (the
// run store's writer, the campaign's workers, Python's): a worker is a fork server started with
// posix_spawn (`EXE network-worker`, a hidden command of ncosim's command line) and
// single-threaded, which forks one child per run. The child reads the run's [[network]] tables
// again, builds the networks with the same registry and runs them in lockstep with the caller's run
// engine over a socket (network/backend.h's calls, batched: one round trip per advance_to); the
// estimators stay in the caller's threads. The campaign's thread keeps its server from run to run
// (WorkerPool).
//
// Death: a child dies with its server (a parent-death signal, reliable in a single-threaded
// process) and at end of file on its socket; a server dies at end of file on its socket (its
// parent ended, however: kill -9 included), killing its child first. So no worker outlives the
// process that started it, and none holds what the parent held (file locks, threads, the GIL).
#pragma once

#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "network/backend.h"

namespace ncosim::network {

// The executable a worker runs as `EXE network-worker`: ncosim itself, or a program of yours whose
// main calls run_cli (the command line sets its own executable; the Python module the installed
// ncosim's). Without one, a run that needs a worker throws, saying so.
void set_worker_executable(const std::string& path);
std::string worker_executable();

// A network of a run in a worker: its kind and its table's TOML text (NetworkEntry::table).
struct WorkerNetwork {
  std::string kind;
  std::string table;
};

class WorkerServer;

// The fork servers of a scenario's runs: one per run in progress, kept from run to run, ended
// (with any child) when the pool is destroyed. Thread-safe.
class WorkerPool {
 public:
  WorkerPool();
  ~WorkerPool();
  WorkerPool(const WorkerPool&) = delete;
  WorkerPool& operator=(const WorkerPool&) = delete;

  // Run `run` of `networks` (one engine's, in scenario order) with `senders` in a child process
  // of a server. Throws std::runtime_error when no server can start or the child refuses the
  // networks; the run's calls throw EngineFailure when the child dies, std::runtime_error when
  // its server dies.
  std::unique_ptr<NetworkRun> start(const std::vector<WorkerNetwork>& networks,
                                    const std::vector<Sender>& senders, std::uint64_t seed,
                                    std::uint64_t run);

  // A server back from a run that ended cleanly (WorkerServer's RemoteRun), for the next run.
  void give_back(std::unique_ptr<WorkerServer> server);

 private:
  std::mutex mutex_;
  std::vector<std::unique_ptr<WorkerServer>> idle_;
};

// `EXE network-worker` (file descriptor 3: the socket to its parent): serves forks until its
// parent closes the socket; `kinds` reads the children's tables. Returns the exit status.
int worker_main(const NetworkRegistry& kinds);

}  // namespace ncosim::network
