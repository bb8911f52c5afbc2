// sim/analysis/validity.cc — the model_check note of summary.csv.
#include "sim/analysis/validity.h"

#include <fmt/format.h>

#include <algorithm>
#include <boost/math/distributions/students_t.hpp>
#include <cmath>
#include <vector>

#include "sim/analysis/summary_row.h"
#include "sim/scenario/scenario.h"

namespace ncosim::sim {

namespace {

std::string link_name(const Scenario& sc, int link) {
  const auto& l = sc.links[static_cast<std::size_t>(link)];
  return fmt::format("link '{}' ({})", l.name, l.kind);
}

// A link that is a node of a [[network]]: its losses and delays come from the network's simulation.
std::string network_departure(const Scenario& sc, const models::NetworkAttachment& a) {
  const auto& net = sc.networks[static_cast<std::size_t>(a.network)];
  return fmt::format(
      "network '{}' ({}): losses and delays come from its simulation, correlated across its "
      "senders; the design uses only each link's design_pmf",
      net.name, net.kind);
}

}  // namespace

std::string design_model_departure(const Scenario& sc, std::size_t e) {
  std::vector<std::string> why;
  if (sc.plant_vehicle >= 0)
    why.emplace_back("the plant is a SUMO vehicle, not a linear system with Gaussian noise");
  if (!sc.disturbance.empty())
    why.emplace_back("a deterministic disturbance the design does not know");
  const auto& entry = sc.estimators[e];
  const bool fictitious = entry.design->models_independent_fictitious_sensors();
  const Eigen::Index n = sc.model.plant.n();
  const Eigen::Index ext = entry.design->extended_size();
  const int max_delay = n > 0 && ext > 0 ? static_cast<int>(ext / n) - 1 : 0;
  std::vector<std::string> physical;  // links with one copy per sample and several possible delays
  for (const auto& s : sc.model.sensors) {
    const auto& spec = s.spec;
    if (!spec.policy->sends_every_sample()) {
      why.push_back(
          fmt::format("sensor '{}' sends by policy \"{}\" (what arrives depends on the state)",
                      spec.name, spec.policy->name()));
      continue;
    }
    if (fictitious && spec.every > 1) {
      why.push_back(
          fmt::format("sensor '{}' samples every {} periods (the design treats it as a rate)",
                      spec.name, spec.every));
    }
    if (spec.link < 0) continue;  // ideal: q[0] = 1
    const auto& l = sc.links[static_cast<std::size_t>(spec.link)];
    if (l.link->network_attachment() != nullptr) {
      why.push_back(network_departure(sc, *l.link->network_attachment()));
      continue;
    }
    using LossModel = models::LinkReporting::LossModel;  // each kind says how (models/link.h)
    const LossModel loss_model = models::loss_model_of(*l.link);
    if (loss_model == LossModel::kPosition) {
      why.push_back(
          fmt::format("SUMO {}: reception depends on the vehicles' distance, losses come in bursts",
                      link_name(sc, spec.link)));
      continue;
    }
    if (loss_model != LossModel::kIndependent) {
      why.push_back(
          fmt::format("{}: bursty or recorded losses; the design uses only the marginal law",
                      link_name(sc, spec.link)));
      continue;
    }
    if (!fictitious || l.link->independent_copies())
      continue;  // independent copies: Dolz Remark 2.3, the model itself
    // One copy per sample: the model holds when at most one delay d <= max_delay can occur.
    const auto pmf = l.link->delay_pmf(max_delay);
    int possible = 0;
    for (double p : pmf) possible += p > 0.0;
    if (possible > 1) {
      const std::string name = fmt::format("'{}'", l.name);
      if (std::find(physical.begin(), physical.end(), name) == physical.end())
        physical.push_back(name);
    } else if (spec.buffer > 0 && !spec.fresh_resend_noise) {
      why.push_back(
          fmt::format("sensor '{}' re-sends buffered samples with their own noise (resend_noise = "
                      "\"same\"); the design assumes fresh noise",
                      spec.name));
    }
  }
  if (!physical.empty()) {
    std::string names;
    for (const auto& p : physical) names += (names.empty() ? "" : ", ") + p;
    why.push_back(fmt::format(
        "physical packets on delay link{} {}: one copy per sample, several possible delays <= "
        "max_delay; the design assumes independent copies per delay",
        physical.size() > 1 ? "s" : "", names));
  }
  // One mention per distinct reason (two sensors on one link give the same text).
  std::string out;
  for (std::size_t i = 0; i < why.size(); ++i) {
    if (std::find(why.begin(), why.begin() + static_cast<std::ptrdiff_t>(i), why[i]) !=
        why.begin() + static_cast<std::ptrdiff_t>(i))
      continue;
    out += (out.empty() ? "" : "; ") + why[i];
  }
  return out;
}

std::string model_check_note(const Scenario& sc, std::size_t e, const SummaryRow& row) {
  // The prediction and the simulated value it predicts: mse_ext (tr Pt) first, else mse.
  const char* metric = nullptr;
  std::optional<double> predicted, simulated, ci;
  if (row.predicted_mse_ext) {
    metric = "mse_ext";
    predicted = row.predicted_mse_ext;
    simulated = row.mse_ext;
    ci = row.mse_ext_ci95;
  } else if (row.predicted_mse) {
    metric = "mse";
    predicted = row.predicted_mse;
    simulated = row.mse;
    ci = row.mse_ci95;
  } else {
    return "";
  }
  const std::string departure = design_model_departure(sc, e);
  const std::string sim_text =
      simulated ? fmt::format("{:.4g}", *simulated) : fmt::format("none ({})", row.status);
  if (!departure.empty()) {
    return fmt::format("design model not followed ({}): predicted {} {:.4g}, simulated {}",
                       departure, metric, *predicted, sim_text);
  }
  if (!simulated)
    return fmt::format("no simulated {} to check (status {}); predicted {:.4g}", metric, row.status,
                       *predicted);
  if (!ci || row.runs < 2 || row.status == "heavy_tail") {
    return fmt::format(
        "no Monte Carlo error to check against ({}): predicted {} {:.4g}, simulated {:.4g}",
        row.runs < 2                 ? "1 run"
        : row.status == "heavy_tail" ? "heavy_tail"
                                     : "no CI",
        metric, *predicted, *simulated);
  }
  // 99.9 % half-width from the 95 % one: the same s / sqrt(R), another t quantile.
  const boost::math::students_t t(static_cast<double>(row.runs - 1));
  const double mc = *ci * boost::math::quantile(boost::math::complement(t, 0.0005)) /
                    boost::math::quantile(boost::math::complement(t, 0.025));
  const double gap = *simulated - *predicted;
  if (std::abs(gap) <= mc) {
    return fmt::format(
        "consistent: simulated {} {:.4g} within {:.2g} (99.9 % MC error) of the prediction {:.4g}",
        metric, *simulated, mc, *predicted);
  }
  return fmt::format(
      "MISMATCH: simulated {} {:.4g} is {:+.3g} ({:+.1f} %) from the prediction {:.4g}, beyond the "
      "99.9 % "
      "MC error {:.2g}, although the design model is followed",
      metric, *simulated, gap, 100.0 * gap / *predicted, *predicted, mc);
}

}  // namespace ncosim::sim
