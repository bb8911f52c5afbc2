// sim/run/overload.h — overload told (results/README.md, "Overload and growth"). For every flow of
// links.csv: its offered and delivered rates and whether its delays grow through the run (the
// trend test of sim/run/trend.h on the means of its delay blocks, models::DelayBlocks); a flow over
// a link whose queue can grow (a node of a [[network]]) that falls behind its offered rate while
// its delays grow is `overloaded`: a note under the summary table and, with `run
// --fail-on-status`, a failure. A growth alone (a `sumo_distance` receiver driving away, a trace
// recorded from an overloaded network) is a `trend`: a note, never a failure. For every estimator
// whose error grows through the run without diverging (the same test on its log block MSE,
// EstimatorRunMetrics::sse_blocks): a note. Never throws.
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "sim/run/link_report.h"

namespace ncosim::sim {

// An error trend is told only when the fitted block MSE grows by at least this factor over the
// run (and the test is significant at kTrendAlpha, link_report.h).
inline constexpr double kMinErrorFactor = 1.25;

// Estimator e's error trend: the test on the runs' log block MSE; nullopt when any run diverged
// or no run has every block finite and positive.
std::optional<TrendResult> error_trend(const CampaignResult& res, std::size_t e);
// Whether that trend is told: significant at kTrendAlpha and grown by kMinErrorFactor.
bool error_grows(const TrendResult& t);

// The notes under the summary table, one paragraph per told flow or estimator (each starting with
// "\n"); "" when there is none.
std::string growth_notes(const std::vector<SweepAxis>& sweeps,
                         const std::vector<std::vector<std::string>>& labels,
                         const std::vector<const Scenario*>& scenarios,
                         const std::vector<const CampaignResult*>& results);

// One line per overloaded flow ("[case, ]link 'L' (sender 'S'): overloaded ..."), for
// --fail-on-status.
std::vector<std::string> overloaded_flows(const std::vector<SweepAxis>& sweeps,
                                          const std::vector<std::vector<std::string>>& labels,
                                          const std::vector<const Scenario*>& scenarios,
                                          const std::vector<const CampaignResult*>& results);

}  // namespace ncosim::sim
