// sim/cmd/mpi_campaign.h — `mpirun -n K ncosim run FILE`: runs distributed over MPI ranks
// (Boost.MPI) through a dynamic work queue (one run per request, so unequal nodes balance). Rank 0
// owns the run store and the exports and simulates too; ranks 1..K-1 simulate the runs rank 0 hands
// out and send back each run's serialized metrics. Results are bit-identical to one process (every
// run depends on (seed, run index) alone). A scenario with networks runs them as everywhere else
// (network/worker.h: each run's ns-3 in a worker process the rank spawns, which never calls MPI).
// Built when NCOSIM_MPI is ON (Boost.MPI + an MPI library found); otherwise a run under mpirun with
// more than one rank is refused.
#pragma once

#include <cstdint>
#include <memory>

#include "sim/run/campaign.h"

namespace ncosim::sim {

// True when this process was started by mpirun/mpiexec as one of several ranks (Open MPI,
// MPICH and PMI environments).
bool mpi_launched();
bool mpi_available();

// Under mpirun, every rank ends with the exit code of rank 0, and only rank 0 reports an error
// it found: ranks > 0 wait in serve() for rank 0's word. MPI outlives the session (an error
// unwinding the stack must not MPI_Abort, which loses rank 0's message): mpi_finish ends it.
class MpiSession {
 public:
  MpiSession();   // MPI_Init_thread (serialized); throws std::runtime_error without MPI support
  ~MpiSession();  // keeps MPI open for mpi_finish (at the latest, at exit: as mpi_finish(0))
  MpiSession(const MpiSession&) = delete;
  MpiSession& operator=(const MpiSession&) = delete;

  int rank() const;
  int size() const;
  // Rank 0: the runs of `options.only_runs` of case `case_index`, over every rank (rank 0 with
  // `options.threads` local threads); each result goes to `options.on_run`. No trace; the
  // timing (when asked) replays the first run locally after the distribution.
  CampaignResult run(const Scenario& sc, std::size_t case_index, const CampaignOptions& options);
  // Ranks > 0: simulate what rank 0 sends until it says stop (with rank 0's exit code, which
  // mpi_finish returns). `cases` are the loaded cases.
  void serve(const std::vector<const Scenario*>& cases);

  // See mpi_finish.
  static int finish(int exit_code);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  static std::unique_ptr<Impl>& ended();  // the Impl of a destroyed session, until finish
};

// The runs of case `case_index` of `options`: over every rank with `mpi` (under mpirun), else over
// this process's threads (run_campaign). The one place where a campaign chooses how to run: a
// scenario with networks runs the same way (its engines' worker processes are the network layer's
// business, network/worker.h).
CampaignResult run_case(const Scenario& sc, std::size_t case_index, const CampaignOptions& options,
                        MpiSession* mpi);

// The process's exit code once MPI is done (call it last, after the error, if any, is printed).
// Without an MPI session: `exit_code`. Rank 0: tells every worker to stop with `exit_code`, then
// MPI_Finalize; returns `exit_code`. Ranks > 0: MPI_Finalize; returns `exit_code` if not 0, else
// the exit code rank 0 sent.
int mpi_finish(int exit_code);

}  // namespace ncosim::sim
