// sim/run/physical.h — the physical state of a re-centred run (scenarios/README.md, re-centring).
// The simulation adds the known input r[k] = -A x[k] so that x stays small; the plant without
// it has x_p[k] = x[k] + o[k] with o[0] = 0 and o[k] = A_m o[k-1] + A x[k-1] (A_m the matrix of
// the transition into period k: the mode's A for jump plants, else A). Estimates shift by the same
// o[k] (every estimator knows r). Sums in long double; past |x_p| > 1e10 the physical values
// would carry rounding larger than the noise (an unstable plant), so they are left out from there.
#pragma once

#include <optional>
#include <vector>

#include "sim/run/run_results.h"
#include "sim/scenario/scenario.h"

namespace ncosim::sim {

// |x_p| beyond which the physical state is not written (the precision_lost limit of a run).
inline constexpr double kPhysicalLimit = 1e10;

// Per trace row: the offset o[k] to add to x and xhat, or nullopt once |x_p| exceeded the limit.
// Empty when the scenario was not re-centred.
std::vector<std::optional<std::vector<double>>> recentring_offsets(
    const Scenario& sc, const std::vector<TraceRow>& trace);

}  // namespace ncosim::sim
