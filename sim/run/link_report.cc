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

// Packets sender `flow` handed to the link in one run (`r`: its counters; `m`: the run's metrics).
// A network link counts a packet when its fate is known, so a packet still queued when the run
// ends is in no counter: a sensor that sends every sample offered ceil(periods / every), an
// actuator one command per period; a send-on-delta sensor's sent samples (counted from the
// warm-up on) are scaled to the whole run.
double offered(const Scenario& sc, const LinkFlow& flow, bool queue, const models::LinkCounters& r,
               const RunMetrics& m) {
  if (!queue) return static_cast<double>(r.sent);
  const std::int64_t periods = sc.run.periods;
  if (flow.actuator) return static_cast<double>(periods);
  const auto& spec = sc.model.sensors[flow.sender].spec;
  if (spec.policy->sends_every_sample())
    return static_cast<double>((periods + spec.every - 1) / spec.every);
  const std::int64_t counted = periods - sc.run.warmup;
  if (m.empty() || flow.sender >= m[0].sensor_sent.size() || counted <= 0)
    return static_cast<double>(r.sent);
  return static_cast<double>(m[0].sensor_sent[flow.sender]) * static_cast<double>(periods) /
         static_cast<double>(counted);
}

// One run's blocks as means at their centres (a share of the packets counted in the run): the
// mean delay of the delivered packets of each block that has one, and each block's loss ratio.
struct RunSeries {
  BlockSeries delay, loss;
};
RunSeries run_series(const models::LinkCounters& r) {
  RunSeries s;
  const models::DelayBlocks& b = r.blocks;
  if (r.sent <= 0) return s;
  const auto size = static_cast<double>(b.size);
  for (std::size_t i = 0; i < b.delivered.size() && i < b.delay.size(); ++i) {
    const double t = (static_cast<double>(i) + 0.5) * size / static_cast<double>(r.sent);
    const auto got = static_cast<double>(b.delivered[i]);
    s.loss.t.push_back(t);
    s.loss.y.push_back(1.0 - got / size);
    if (b.delivered[i] <= 0) continue;
    s.delay.t.push_back(t);
    s.delay.y.push_back(static_cast<double>(b.delay[i]) / got);
  }
  return s;
}

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

// offered_rate .. overload (results/README.md, "Overload and growth").
std::string load_cells(const FlowLoad& load) {
  const auto trend = [](const std::optional<TrendResult>& t) {
    if (!t) return std::string(",,,");
    return fmt::format("{},{},{},{}", fmt_number(t->first), fmt_number(t->last),
                       fmt_number(t->growth), fmt_number(t->p));
  };
  return fmt::format("{},{},{},{},{}", fmt_number(load.offered_rate),
                     fmt_number(load.delivered_rate), trend(load.delay), trend(load.loss),
                     load.verdict);
}

}  // namespace

std::vector<FlowLoad> flow_loads(const Scenario& sc, const CampaignResult& res,
                                 const std::vector<LinkFlow>& flows) {
  static const RunMetrics kNoMetrics;
  std::vector<FlowLoad> out(flows.size());
  for (std::size_t f = 0; f < flows.size(); ++f) {
    FlowLoad& load = out[f];
    load.queue = sc.links[flows[f].link].link->network_attachment() != nullptr;
    double offer = 0.0, delivered = 0.0, runs = 0.0;
    std::vector<BlockSeries> delays, losses;
    for (std::size_t r = 0; r < res.link_runs.size(); ++r) {
      if (f >= res.link_runs[r].size()) continue;  // a failed run: no counters
      const models::LinkCounters& c = res.link_runs[r][f];
      offer += offered(sc, flows[f], load.queue, c, r < res.runs.size() ? res.runs[r] : kNoMetrics);
      delivered += static_cast<double>(c.delivered);
      runs += 1.0;
      RunSeries s = run_series(c);
      delays.push_back(std::move(s.delay));
      losses.push_back(std::move(s.loss));
    }
    if (runs == 0.0 || sc.run.periods <= 0) continue;
    load.offered_rate = offer / (runs * static_cast<double>(sc.run.periods));
    load.delivered_rate = delivered / (runs * static_cast<double>(sc.run.periods));
    load.delay = trend_test(delays, kMinTrendBlocks);
    load.loss = trend_test(losses, kMinTrendBlocks);
    if (!load.delay && !load.loss) continue;
    const auto grows = [](const std::optional<TrendResult>& t, double by) {
      return t && t->p < kTrendAlpha && t->growth >= by;
    };
    const bool delay_grows = grows(load.delay, kMinDelayGrowth);
    if (load.queue && delay_grows && load.delivered_rate < load.offered_rate) {
      load.verdict = "overloaded";
    } else {
      load.verdict = delay_grows || grows(load.loss, kMinLossGrowth) ? "trend" : "none";
    }
  }
  return out;
}

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
      "drops_no_ack,drops_out_of_range,busy_ratio,offered_rate,delivered_rate,delay_first,delay_"
      "last,delay_growth,delay_trend_p,loss_first,loss_last,loss_growth,loss_trend_p,overload\n";
  for (std::size_t c = 0; c < scenarios.size(); ++c) {
    const Scenario& sc = *scenarios[c];
    const CampaignResult& res = *results[c];
    const std::vector<LinkFlow> flows = link_flows(sc);
    const std::vector<FlowLoad> loads = flow_loads(sc, res, flows);
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
          "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}\n",
          csv_field(sc.links[flow.link].name), csv_field(sc.links[flow.link].kind),
          csv_field(flow.sender_name), res.link_runs.size(), sum.sent, sum.delivered,
          fmt_number(sum.sent > 0 ? std::optional<double>(static_cast<double>(sum.delivered) /
                                                          static_cast<double>(sum.sent))
                                  : std::nullopt),
          fmt_number(nominal.delivered_ratio), sum.copies.empty() ? "" : std::to_string(max_delay),
          ratios(sum.copies, sum.sent, sum.copies.size()), join(nominal.delay_pmf), b.count,
          fmt_number(b.mean), fmt_number(nominal.burst_mean), opt_int(b.p95), opt_int(b.max),
          ratios(sum.states, sum.sent, states), join(nominal.states), flow.step,
          stack_cells(sum.stack), load_cells(loads[f]));
    }
  }
  return out;
}

}  // namespace ncosim::sim
