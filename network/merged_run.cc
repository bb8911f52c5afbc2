// network/merged_run.cc — a run's networks split by engine and merged back
// (network/merged_run.h).
#include "network/merged_run.h"

#include <algorithm>
#include <utility>

#include "network/networks.h"

namespace ncosim::network {

namespace {

class MergedRun final : public NetworkRun {
 public:
  struct Part {
    std::unique_ptr<NetworkRun> run;
    std::vector<int> senders;  // the scenario's index of each of its senders
  };
  struct Index {
    std::size_t part = 0;
    int local = 0;
  };
  MergedRun(std::vector<Part> parts, std::vector<Index> senders, std::vector<Index> networks)
      : parts_(std::move(parts)), senders_(std::move(senders)), networks_(std::move(networks)) {}

  void send(int sender, std::uint64_t id, Nanoseconds t) override {
    const Index& i = senders_[static_cast<std::size_t>(sender)];
    parts_[i.part].run->send(i.local, id, t);
  }
  // Part by part: the fates of one instant keep each engine's order, engines in scenario order.
  void advance_to(Nanoseconds t, std::vector<Fate>& fates) override {
    for (Part& p : parts_) {
      const std::size_t from = fates.size();
      p.run->advance_to(t, fates);
      for (std::size_t f = from; f < fates.size(); ++f)
        fates[f].sender = p.senders[static_cast<std::size_t>(fates[f].sender)];
    }
  }
  void move_sender(int sender, double x, double y, double z, Nanoseconds t) override {
    const Index& i = senders_[static_cast<std::size_t>(sender)];
    parts_[i.part].run->move_sender(i.local, x, y, z, t);
  }
  void move_sink(int network, double x, double y, double z, Nanoseconds t) override {
    const Index& i = networks_[static_cast<std::size_t>(network)];
    parts_[i.part].run->move_sink(i.local, x, y, z, t);
  }
  MacCounters counters(int sender) const override {
    const Index& i = senders_[static_cast<std::size_t>(sender)];
    return parts_[i.part].run->counters(i.local);
  }

 private:
  std::vector<Part> parts_;
  std::vector<Index> senders_, networks_;
};

}  // namespace

std::unique_ptr<NetworkRun> start_merged(const std::vector<const NetworkDesign*>& designs,
                                         const std::vector<Sender>& senders,
                                         const StartPart& start) {
  std::vector<const NetworkEngine*> engines;
  std::vector<MergedRun::Index> networks(designs.size());
  for (std::size_t n = 0; n < designs.size(); ++n) {
    const NetworkEngine* e = &designs[n]->engine();
    const auto at = std::find(engines.begin(), engines.end(), e);
    networks[n].part = static_cast<std::size_t>(at - engines.begin());
    if (at == engines.end()) engines.push_back(e);
  }
  if (engines.size() == 1) {
    std::vector<std::size_t> all(designs.size());
    for (std::size_t n = 0; n < all.size(); ++n) all[n] = n;
    return start(*engines.front(), all, senders);
  }
  std::vector<MergedRun::Part> parts(engines.size());
  std::vector<std::vector<std::size_t>> owned(engines.size());
  for (std::size_t n = 0; n < designs.size(); ++n) {
    std::vector<std::size_t>& own = owned[networks[n].part];
    networks[n].local = static_cast<int>(own.size());
    own.push_back(n);
  }
  std::vector<std::vector<Sender>> local(engines.size());
  std::vector<MergedRun::Index> index(senders.size());
  for (std::size_t s = 0; s < senders.size(); ++s) {
    const MergedRun::Index& n = networks[static_cast<std::size_t>(senders[s].network)];
    index[s] = {n.part, static_cast<int>(local[n.part].size())};
    Sender x = senders[s];
    x.network = n.local;
    local[n.part].push_back(x);
    parts[n.part].senders.push_back(static_cast<int>(s));
  }
  for (std::size_t p = 0; p < engines.size(); ++p)
    parts[p].run = start(*engines[p], owned[p], local[p]);
  return std::make_unique<MergedRun>(std::move(parts), std::move(index), std::move(networks));
}

std::unique_ptr<NetworkRun> start_here(const std::vector<const NetworkDesign*>& networks,
                                       const std::vector<Sender>& senders, std::uint64_t seed,
                                       std::uint64_t run) {
  return start_merged(networks, senders,
                      [&](const NetworkEngine& engine, const std::vector<std::size_t>& own,
                          const std::vector<Sender>& local) {
                        std::vector<const NetworkDesign*> designs;
                        for (const std::size_t n : own) designs.push_back(networks[n]);
                        return engine.start(designs, local, seed, run);
                      });
}

}  // namespace ncosim::network
