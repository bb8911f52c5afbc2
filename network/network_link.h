// network/network_link.h — the `network` link kind: a [[link]] that is a node of a [[network]].
// Its packets' fate comes from the network's simulation (network/network.h), not from a law; the
// law an offline design assumes is the optional `design_pmf` (e.g. fitted by `ncosim fit` to a
// recorded trace of the network), and a design that needs it without it is refused.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "models/link.h"
#include "models/link_factory.h"

namespace ncosim::network {

class NetworkLink final : public models::Link {
 public:
  // `no_law`: the message of a design asking for the law when `design_pmf` is empty.
  NetworkLink(models::NetworkAttachment attachment, std::vector<double> design_pmf,
              std::string no_law);
  std::unique_ptr<models::Link> clone() const override;
  std::int64_t transmit(kernel::Rng& rng) override;  // never called: the network decides
  std::vector<double> delay_pmf(int max_delay) const override;
  double loss_probability() const override;
  bool law_known() const override { return !design_pmf_.empty(); }
  const models::NetworkAttachment* network_attachment() const override { return &attachment_; }

 private:
  models::NetworkAttachment attachment_;
  std::vector<double> design_pmf_;
  std::string no_law_;
};

}  // namespace ncosim::network
