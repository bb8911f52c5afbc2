// sim/analysis/validity.h — the model_check column of summary.csv: does a row's simulated error
// agree with its design's analytic prediction? Where the simulation follows the design model (the
// jump observer's independent-packet arrival model, Schenato's i.i.d. delays for static_buffer)
// a simulated value outside the prediction by more than the Monte Carlo error (99.9 % Student-t
// half-width of the run spread) is reported as a mismatch; where the scenario knowingly departs
// from that model (physical packets with several possible delays, bursty or trace links, SUMO,
// send-on-delta sensors, a deterministic disturbance) the note says so instead of comparing.
// A note, never a failure; empty where the row has no prediction. Never throws.
#pragma once

#include <cstddef>
#include <string>

namespace ncosim::sim {

struct Scenario;
struct SummaryRow;

// The reason the scenario departs from estimator `e`'s design model, "" when it follows it.
std::string design_model_departure(const Scenario& sc, std::size_t e);

// The note for one row of summary.csv (estimator `e` of the case `sc`).
std::string model_check_note(const Scenario& sc, std::size_t e, const SummaryRow& row);

}  // namespace ncosim::sim
