// sim/store/store_format.h — the run store's records: the exact, versioned binary form of one run's
// metrics (every estimator) and of its link counters, and the store's error (a malformed record,
// or any failure of the store: sim/store/store.h).
#pragma once

#include <stdexcept>
#include <string>

#include "sim/run/run_results.h"

namespace ncosim::sim {

class StoreError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Binary form of one run's metrics (every estimator): exact (doubles by their bits), versioned.
std::string serialize_run(const RunMetrics& m);
// Throws StoreError on a malformed or truncated blob.
RunMetrics deserialize_run(const std::string& blob);

// Binary form of one run's link counters (every flow): exact, versioned. Throws StoreError
// on a malformed or truncated blob.
std::string serialize_links(const RunLinks& links);
RunLinks deserialize_links(const std::string& blob);

}  // namespace ncosim::sim
