// sim/present/plot_trace.h — `ncosim plot --trace`: run 0's true state and estimates against time,
// packet arrivals marked, from trajectory.csv (sim/present/plot.h builds it with the others).
#pragma once

#include <string>

#include "sim/present/figure.h"

namespace ncosim::sim {

// The trace figure of folder `dir` over opt.trace_from .. + opt.trace_periods. Throws
// ScenarioError when trajectory.csv is missing or malformed.
Figure trace_figure(const std::string& dir, const PlotOptions& opt);

}  // namespace ncosim::sim
