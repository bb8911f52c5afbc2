// network/network_link.cc — the `network` link kind (network/network_link.h).
#include "network/network_link.h"

#include <fmt/format.h>

#include <algorithm>
#include <numeric>
#include <utility>

#include "config/config.h"
#include "kernel/check.h"
#include "network/network.h"

namespace ncosim::network {

NetworkLink::NetworkLink(models::NetworkAttachment attachment, std::vector<double> design_pmf,
                         std::string no_law)
    : attachment_(attachment), design_pmf_(std::move(design_pmf)), no_law_(std::move(no_law)) {}

std::unique_ptr<models::Link> NetworkLink::clone() const {
  return std::make_unique<NetworkLink>(*this);
}

std::int64_t NetworkLink::transmit(kernel::Rng&) {
  NCOSIM_CHECK(false);  // the run sends a network link's packets through its network
  return models::kLost;
}

std::vector<double> NetworkLink::delay_pmf(int max_delay) const {
  if (design_pmf_.empty()) throw config::ScenarioError(no_law_);
  std::vector<double> pmf(static_cast<std::size_t>(max_delay) + 1, 0.0);
  for (std::size_t d = 0; d < pmf.size() && d < design_pmf_.size(); ++d) pmf[d] = design_pmf_[d];
  return pmf;
}

double NetworkLink::loss_probability() const {
  if (design_pmf_.empty()) throw config::ScenarioError(no_law_);
  return std::max(0.0, 1.0 - std::accumulate(design_pmf_.begin(), design_pmf_.end(), 0.0));
}

namespace {

using config::Key;

const config::Keys& network_link_keys() {
  static const config::Keys keys{
      Key::string("network").help("the [[network]] this link is a node of (its name)"),
      Key::integer("bytes").range(1, 1500).or_default(32).unit("bytes").help(
          "payload of each packet (the stack adds its own headers)"),
      Key::numbers("position")
          .optional("[0, 0, 0]")
          .entries(3)
          .unit("m")
          .help("[x, y, z] of this node, for the network kinds with positions (the sink's is the "
                "network's sink_position)"),
      Key::string("vehicle")
          .optional("none: the fixed `position`")
          .help("a [sumo] vehicle this node rides: its position is the vehicle's (x, y, z = 1.5 m) "
                "at every period; while the vehicle is not in the traffic its packets are lost "
                "(not sent) and the node is out of everyone's range (not with `position`)"),
      Key::numbers("design_pmf")
          .optional("none: a design that needs the law is refused")
          .probability()
          .help("the delay law the offline designs assume: P[delay = d periods], d = 0, 1, ...; "
                "the rest lost (e.g. from `ncosim fit` on the network's recorded trace)"),
  };
  return keys;
}

std::unique_ptr<models::Link> read_network_link(const config::Table& t,
                                                const models::LinkContext& ctx) {
  const config::KeyReader r(t, network_link_keys());
  const std::string name = r.string("network");
  const auto it = std::find(ctx.networks.begin(), ctx.networks.end(), name);
  if (it == ctx.networks.end()) {
    std::string names;
    for (const auto& n : ctx.networks)
      names += (names.empty() ? "" : ", ") + fmt::format("\"{}\"", n);
    t.fail("network", fmt::format("expected the name of a [[network]] ({}), got \"{}\"",
                                  names.empty() ? "the scenario has none" : names, name));
  }
  std::vector<double> pmf;
  if (r.has("design_pmf")) {
    pmf = r.numbers("design_pmf");
    double sum = 0.0;
    for (const double p : pmf) {
      if (!(p >= 0.0 && p <= 1.0)) t.fail("design_pmf", "expected probabilities in [0, 1]");
      sum += p;
    }
    if (sum > 1.0 + 1e-12)
      t.fail("design_pmf",
             fmt::format("expected probabilities that sum to at most 1, got {}", sum));
  }
  const std::string no_law = config::format_error(
      t.file(), t.line(), t.key_path("design_pmf"),
      "a design needs this link's delay law, which its network decides during the run: give "
      "design_pmf = [P(delay 0), P(delay 1), ...] (`ncosim record-link` on the network, then "
      "`ncosim fit`), or use estimators that need no law");
  models::NetworkAttachment a{static_cast<int>(it - ctx.networks.begin()),
                              static_cast<std::uint32_t>(r.integer("bytes"))};
  if (r.has("vehicle")) {
    if (r.has("position")) t.fail("vehicle", "expected `vehicle` or `position`, not both");
    if (!ctx.mobility)
      t.fail("vehicle",
             "expected a [sumo] table (the vehicles' mobility) for a node that rides a "
             "vehicle");
    a.vehicle = ctx.mobility->vehicle(t, "vehicle");
  }
  if (r.has("position")) {
    const std::array<double, 3> p = read_xyz(t, r, "position");
    a.x = p[0];
    a.y = p[1];
    a.z = p[2];
  }
  return std::make_unique<NetworkLink>(a, std::move(pmf), no_law);
}

}  // namespace

void register_network_links(models::LinkRegistry& registry) {
  registry.add("network",
               "a node of a [[network]] (ns-3): its packets contend with the network's other "
               "senders: network, bytes, position or vehicle, design_pmf",
               network_link_keys(), read_network_link);
}

}  // namespace ncosim::network
