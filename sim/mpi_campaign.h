// sim/mpi_campaign.h — `mpirun -n K ncosim run FILE`: runs distributed over MPI ranks (Boost.MPI)
// through a dynamic work queue (one run per request, so unequal nodes balance). Rank 0 owns the
// run store and the exports and simulates too; ranks 1..K-1 simulate the runs rank 0 hands out
// and send back each run's serialized metrics. Results are bit-identical to one process (every
// run depends on (seed, run index) alone). Built when NCOSIM_MPI is ON (Boost.MPI + an MPI
// library found); otherwise a run under mpirun with more than one rank is refused.
#pragma once

#include <cstdint>
#include <memory>

#include "sim/campaign.h"

namespace ncosim::sim {

// True when this process was started by mpirun/mpiexec as one of several ranks (Open MPI,
// MPICH and PMI environments).
bool mpi_launched();
bool mpi_available();

class MpiSession {
 public:
  MpiSession();   // MPI_Init_thread (serialized); throws std::runtime_error without MPI support
  ~MpiSession();  // rank 0: tells every worker to stop; MPI_Finalize
  MpiSession(const MpiSession&) = delete;
  MpiSession& operator=(const MpiSession&) = delete;

  int rank() const;
  int size() const;
  // Rank 0: the runs of `options.only_runs` of case `case_index`, over every rank (rank 0 with
  // `options.threads` local threads); each result goes to `options.on_run`. No trace; the
  // timing (when asked) replays the first run locally after the distribution.
  CampaignResult run(const Scenario& sc, std::size_t case_index, const CampaignOptions& options);
  // Ranks > 0: simulate what rank 0 sends until it says stop. `cases` are the loaded cases.
  void serve(const std::vector<const Scenario*>& cases);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace ncosim::sim
