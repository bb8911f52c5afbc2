// sim/run/link_report.cc — links.csv.
#include "sim/run/link_report.h"

#include <fmt/format.h>

#include <algorithm>

#include "network/network.h"
#include "sim/files/csv.h"

namespace ncosim::sim {

std::vector<LinkFlow> link_flows(const Scenario& sc) {
  std::vector<LinkFlow> flows;
  for (std::size_t l = 0; l < sc.links.size(); ++l) {
    const std::size_t first = flows.size();
    for (std::size_t s = 0; s < sc.model.sensors.size(); ++s) {
      const auto& spec = sc.model.sensors[s].spec;
      if (spec.link == static_cast<int>(l))
        flows.push_back({l, false, s, spec.name, true, std::nullopt, ""});
    }
    // Sensors naming one link share its channel instance.
    if (flows.size() - first > 1) {
      for (std::size_t f = first; f < flows.size(); ++f) flows[f].sole = false;
    }
    for (std::size_t a = 0; a < sc.model.actuators.size(); ++a) {
      const auto& spec = sc.model.actuators[a].spec;
      if (spec.link == static_cast<int>(l))
        flows.push_back({l, true, a, spec.name, true, std::nullopt, ""});
    }
    using StateStep =
        models::LinkReporting::StateStep;  // the link says what moves its state (models/link.h)
    const StateStep step = models::state_step_of(*sc.links[l].link);
    const bool per_period = step == StateStep::kPeriod;
    for (std::size_t f = first; f < flows.size(); ++f) {
      LinkFlow& flow = flows[f];
      if (step != StateStep::kNone) flow.step = per_period ? "period" : "packet";
      if (!per_period) {
        if (flow.sole) flow.gap = 1;
      } else if (flow.actuator) {
        flow.gap = 1;
      } else {
        const auto& spec = sc.model.sensors[flow.sender].spec;
        if (spec.policy->sends_every_sample()) flow.gap = static_cast<int>(spec.every);
      }
    }
  }
  return flows;
}

FlowIndex flow_index(const Scenario& sc, const std::vector<LinkFlow>& flows) {
  FlowIndex ix;
  ix.sensor.assign(sc.model.sensors.size(), -1);
  ix.actuator.assign(sc.model.actuators.size(), -1);
  for (std::size_t f = 0; f < flows.size(); ++f) {
    (flows[f].actuator ? ix.actuator : ix.sensor)[flows[f].sender] = static_cast<int>(f);
  }
  return ix;
}

namespace {

std::string join(const std::vector<double>& v) {
  std::string out;
  for (std::size_t i = 0; i < v.size(); ++i) out += fmt::format("{}{:.6g}", i ? ";" : "", v[i]);
  return out;
}

std::string ratios(const std::vector<std::int64_t>& counts, std::int64_t total, std::size_t size) {
  std::vector<double> v(size, 0.0);
  for (std::size_t i = 0; i < counts.size() && i < size; ++i) {
    v[i] = static_cast<double>(counts[i]) / static_cast<double>(total);
  }
  return total > 0 ? join(v) : "";
}

std::string opt_int(const std::optional<std::int64_t>& v) { return v ? std::to_string(*v) : ""; }

// The network node's stack columns (mac_attempts .. busy_ratio), empty cells for another link. The
// drop causes are network::Drop's values after kNone: queue, channel access, no ack, out of range.
std::string stack_cells(const std::optional<models::StackCounters>& k) {
  constexpr std::size_t kCauses = 4;
  static_assert(network::kDropCauses == kCauses + 1, "a new network::Drop needs its column here");
  if (!k) return std::string(2 + kCauses, ',');
  std::string out = fmt::format("{},{}", k->attempts, k->retries);
  for (std::size_t c = 1; c <= kCauses; ++c)
    out += fmt::format(",{}", c < k->drops.size() ? k->drops[c] : 0);
  std::optional<double> busy;
  if (k->busy_ns >= 0 && k->simulated_ns > 0)
    busy = static_cast<double>(k->busy_ns) / static_cast<double>(k->simulated_ns);
  return out + "," + fmt_number(busy);
}

}  // namespace

std::string links_csv(const std::vector<SweepAxis>& sweeps,
                      const std::vector<std::vector<std::string>>& labels,
                      const std::vector<const Scenario*>& scenarios,
                      const std::vector<const CampaignResult*>& results) {
  std::string out;
  for (const auto& s : sweeps) out += csv_field(s.key) + ",";
  out +=
      "link,kind,sender,runs,packets_sent,packets_delivered,delivered_ratio,nominal_delivered_"
      "ratio,delay_max,"
      "delay_pmf,nominal_delay_pmf,bursts,burst_mean,nominal_burst_mean,burst_p95,burst_max,state_"
      "occupancy,"
      "nominal_state_occupancy,step,mac_attempts,mac_retries,drops_queue,drops_channel_access,"
      "drops_no_ack,drops_out_of_range,busy_ratio\n";
  for (std::size_t c = 0; c < scenarios.size(); ++c) {
    const Scenario& sc = *scenarios[c];
    const CampaignResult& res = *results[c];
    const std::vector<LinkFlow> flows = link_flows(sc);
    for (std::size_t f = 0; f < flows.size(); ++f) {
      const LinkFlow& flow = flows[f];
      models::LinkCounters sum;
      for (const auto& run : res.link_runs) {
        if (f < run.size()) sum.add(run[f]);
      }
      const models::Link& link = *sc.links[flow.link].link;
      const int max_delay = sum.copies.empty() ? 0 : static_cast<int>(sum.copies.size()) - 1;
      const models::LinkNominal nominal = models::nominal_of(link, max_delay, flow.gap);
      const models::BurstSummary b = models::summarise_bursts(sum.bursts);
      const std::size_t states = std::max(sum.states.size(), nominal.states.size());
      for (const auto& l : labels[c]) out += csv_field(l) + ",";
      out += fmt::format(
          "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}\n",
          csv_field(sc.links[flow.link].name), csv_field(sc.links[flow.link].kind),
          csv_field(flow.sender_name), res.link_runs.size(), sum.sent, sum.delivered,
          fmt_number(sum.sent > 0 ? std::optional<double>(static_cast<double>(sum.delivered) /
                                                          static_cast<double>(sum.sent))
                                  : std::nullopt),
          fmt_number(nominal.delivered_ratio), sum.copies.empty() ? "" : std::to_string(max_delay),
          ratios(sum.copies, sum.sent, sum.copies.size()), join(nominal.delay_pmf), b.count,
          fmt_number(b.mean), fmt_number(nominal.burst_mean), opt_int(b.p95), opt_int(b.max),
          ratios(sum.states, sum.sent, states), join(nominal.states), flow.step,
          stack_cells(sum.stack));
    }
  }
  return out;
}

}  // namespace ncosim::sim
