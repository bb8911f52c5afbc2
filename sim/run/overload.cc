// sim/run/overload.cc — overload and growth told (sim/run/overload.h).
#include "sim/run/overload.h"

#include <fmt/format.h>

#include <cmath>

namespace ncosim::sim {

namespace {

std::string test_text(const TrendResult& t) {
  return t.across_runs ? fmt::format("Student t over {} runs' slopes, p = {:.2g}", t.runs, t.p)
                       : fmt::format("Mann–Kendall on {} batch means of {} run(s), p = {:.2g}",
                                     kBatches, t.runs, t.p);
}

std::string where(const std::vector<SweepAxis>& sweeps, const std::vector<std::string>& labels) {
  std::string out;
  for (std::size_t i = 0; i < labels.size() && i < sweeps.size(); ++i)
    out += fmt::format("{} = {}, ", sweeps[i].key, labels[i]);
  return out;
}

std::string flow_name(const Scenario& sc, const LinkFlow& flow) {
  const auto& l = sc.links[flow.link];
  return fmt::format("link \"{}\" ({}), {} \"{}\"", l.name, l.kind,
                     flow.actuator ? "actuator" : "sender", flow.sender_name);
}

// "mean delay 12 -> 148 periods (...)" for a told growth, "" otherwise.
std::string growth_text(const std::optional<TrendResult>& t, double by, const char* what,
                        const char* unit) {
  if (!t || !(t->p < kTrendAlpha) || t->growth < by) return "";
  return fmt::format(
      "{} {:.4g} -> {:.4g}{} (first block -> last; {:+.4g} over the run by least "
      "squares; {})",
      what, t->first, t->last, unit, t->growth, test_text(*t));
}

std::string flow_note(const Scenario& sc, const LinkFlow& flow, const FlowLoad& load) {
  std::string growth = growth_text(load.delay, kMinDelayGrowth, "mean delay", " periods");
  const std::string loss = growth_text(load.loss, kMinLossGrowth, "loss ratio", "");
  if (!loss.empty()) growth += (growth.empty() ? "" : "; ") + loss;
  const std::string rates = fmt::format("offered {:.4g} packet(s)/period, delivered {:.4g}",
                                        load.offered_rate, load.delivered_rate);
  if (load.verdict == "overloaded") {
    return fmt::format(
        "{}: **overloaded**: {}; {}: its queue grows, so every statistic of this case depends on "
        "the run length",
        flow_name(sc, flow), rates, growth);
  }
  const char* why = !load.queue ? "the link has no queue that could grow"
                    : load.delivered_rate < load.offered_rate ? "its delays do not grow"
                                                              : "it delivers what it is offered";
  return fmt::format("{}: grows through the run: {}; {}: a trend, not an overload ({})",
                     flow_name(sc, flow), growth, rates, why);
}

}  // namespace

std::optional<TrendResult> error_trend(const CampaignResult& res, std::size_t e) {
  std::vector<BlockSeries> series;
  for (const RunMetrics& run : res.runs) {
    if (e >= run.size()) continue;
    const EstimatorRunMetrics& m = run[e];
    if (m.diverged || m.status == "network_failure") return std::nullopt;
    if (m.sse_blocks.size() != static_cast<std::size_t>(kErrorBlocks)) continue;
    BlockSeries s;
    for (std::size_t b = 0; b < m.sse_blocks.size(); ++b) {
      const double v = m.sse_blocks[b];
      if (!(v > 0.0) || !std::isfinite(v)) {
        s.y.clear();
        break;
      }
      s.t.push_back((static_cast<double>(b) + 0.5) / static_cast<double>(kErrorBlocks));
      s.y.push_back(std::log(v));
    }
    if (!s.y.empty()) series.push_back(std::move(s));
  }
  return trend_test(series, static_cast<std::size_t>(kErrorBlocks));
}

bool error_grows(const TrendResult& t) {
  return t.p < kTrendAlpha && t.growth >= std::log(kMinErrorFactor);
}

std::string growth_notes(const std::vector<SweepAxis>& sweeps,
                         const std::vector<std::vector<std::string>>& labels,
                         const std::vector<const Scenario*>& scenarios,
                         const std::vector<const CampaignResult*>& results) {
  std::string out;
  for (std::size_t c = 0; c < scenarios.size(); ++c) {
    const Scenario& sc = *scenarios[c];
    const CampaignResult& res = *results[c];
    const std::string at = where(sweeps, labels[c]);
    if (!res.link_runs.empty()) {
      const std::vector<LinkFlow> flows = link_flows(sc);
      const std::vector<FlowLoad> loads = flow_loads(sc, res, flows);
      for (std::size_t f = 0; f < flows.size(); ++f) {
        if (loads[f].verdict != "overloaded" && loads[f].verdict != "trend") continue;
        out += fmt::format("- {}{}.\n", at, flow_note(sc, flows[f], loads[f]));
      }
    }
    for (std::size_t e = 0; e < sc.estimators.size(); ++e) {
      const std::optional<TrendResult> t = error_trend(res, e);
      if (!t || !error_grows(*t)) continue;
      out += fmt::format(
          "- {}\"{}\": its error grows through the run without diverging (fitted block MSE x{:.3g} "
          "from the first to the last counted period; {}): its mse depends on the run length.\n",
          at, sc.estimators[e].name, std::exp(t->growth), test_text(*t));
    }
  }
  if (out.empty()) return out;
  return fmt::format(
      "\nGrowth through the run (one-sided trend tests at {:g} on block means; links.csv "
      "`overload`):\n{}",
      kTrendAlpha, out);
}

std::vector<std::string> overloaded_flows(const std::vector<SweepAxis>& sweeps,
                                          const std::vector<std::vector<std::string>>& labels,
                                          const std::vector<const Scenario*>& scenarios,
                                          const std::vector<const CampaignResult*>& results) {
  std::vector<std::string> out;
  for (std::size_t c = 0; c < scenarios.size(); ++c) {
    const Scenario& sc = *scenarios[c];
    if (results[c]->link_runs.empty()) continue;
    const std::vector<LinkFlow> flows = link_flows(sc);
    const std::vector<FlowLoad> loads = flow_loads(sc, *results[c], flows);
    for (std::size_t f = 0; f < flows.size(); ++f) {
      if (loads[f].verdict != "overloaded") continue;
      out.push_back(fmt::format("{}{}: overloaded (offered {:.4g}/period, delivered {:.4g})",
                                where(sweeps, labels[c]), flow_name(sc, flows[f]),
                                loads[f].offered_rate, loads[f].delivered_rate));
    }
  }
  return out;
}

}  // namespace ncosim::sim
