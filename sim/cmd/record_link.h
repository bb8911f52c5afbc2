// sim/cmd/record_link.h — `ncosim record-link FILE --link NAME`: the per-packet fate (delay or
// lost) of every packet a campaign sends on one link, in the `trace` link's format (seq,delay), run
// after run, so that `ncosim fit` can fit it and a `trace` link with `segment` can replay it.
//
// The link is driven alone, as the campaign drives it: one instance per run (clone, bind_run
// with the run's mobility, reset with the run's link stream), the mobility advanced to kT before
// the packets of period k, and at each period the packets of its sensors in sensor order. This
// gives exactly the campaign's draws because the fate of a packet depends only on the link, its
// random stream (or counter-based keys) and the send times, and the send times of periodic
// sensors are fixed. Send-on-delta sensors (send times depend on the measurements), actuators
// and links delivering independent copies are refused (exit 2). A network link needs no
// design_pmf to be recorded: its designs are made on a placeholder law (placeholder_design_laws).
//
// A link of kind `network` (a node of a [[network]]) is not alone: its packets' fates come from
// the whole network, where every sender of the scenario contends. Each run is then the campaign's
// run (sim/run/run.h record_network_link), simulated in a process of its own, and ns-3 runs on
// after the last period until every packet has its fate; the delays are those links.csv counts.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "sim/scenario/scenario.h"

namespace ncosim::sim {

struct RecordLinkArgs {
  std::string file;
  std::vector<std::string> sets;
  RunOverrides overrides;
  std::string link;  // [[link]] name
  std::string out;   // default: out/record_<file stem>
  bool quiet = false;
  int threads = 0;  // a network link's runs recorded at a time (0: every core)
};

// The trace of one case: packets of run r in rows r * per_run .. (r + 1) * per_run - 1, each
// its delay in periods or models::kLost.
struct RecordedTrace {
  std::int64_t per_run = 0;  // packets one run sends on the link
  std::vector<std::int64_t> delays;
};

// The --set assignments that give every network link of `file` (after `sets`) without
// design_pmf a placeholder law, so that its designs can be made: a record does not use them (a
// jump design on a network link needs design_pmf, which is what the record is for). `names`
// receives those links' names. Empty when the file cannot be read or parsed (the load reports it).
std::vector<std::string> placeholder_design_laws(const std::string& file,
                                                 const std::vector<std::string>& sets,
                                                 std::vector<std::string>* names = nullptr);

// Records `link` (index into sc.links) over runs 0 .. runs - 1 (a network link's runs up to
// `jobs` at a time, each in a process of its own). Throws ScenarioError when the link cannot be
// recorded (see above), naming the sensor, actuator or link.
RecordedTrace record_link(const Scenario& sc, std::size_t link, std::int64_t runs, int jobs = 1);

// The processes a network link's record uses at a time for --threads (0: every core).
int record_jobs(int threads);

// The command: exit 0; ScenarioError (exit 2) for bad input, nothing written.
int cmd_record_link(const RecordLinkArgs& args);

}  // namespace ncosim::sim
