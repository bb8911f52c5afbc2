// tdma_bus.cc — the `tdma_bus` network kind (tdma_bus.h): a design read from its [[network]]
// table, an engine, and a run that computes every fate from the send times.
#include "tdma_bus.h"

#include <algorithm>
#include <cmath>
#include <deque>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace {

using ncosim::network::Drop;
using ncosim::network::Fate;
using ncosim::network::MacCounters;
using ncosim::network::Nanoseconds;
using ncosim::network::NetworkDesign;
using ncosim::network::NetworkEngine;
using ncosim::network::NetworkRun;
using ncosim::network::Sender;
using ncosim::network::Traffic;

class TdmaDesign final : public NetworkDesign {
 public:
  TdmaDesign(Nanoseconds slot, int slots, std::size_t queue)
      : slot_(slot), slots_(slots), queue_(queue) {}
  const NetworkEngine& engine() const override;
  Nanoseconds slot() const { return slot_; }
  int slots() const { return slots_; }
  std::size_t queue() const { return queue_; }

 private:
  Nanoseconds slot_;
  int slots_;
  std::size_t queue_;
};

// One run: per node, the packets not yet on the air; per run, the fates decided but not yet
// reported (a packet on the air is received at its slot's end).
class TdmaRun final : public NetworkRun {
 public:
  TdmaRun(const std::vector<const TdmaDesign*>& networks, const std::vector<Sender>& senders) {
    std::vector<int> seen(networks.size(), 0);  // nodes of each network so far
    for (const Sender& s : senders) {
      Node n;
      n.bus = networks[static_cast<std::size_t>(s.network)];
      n.slot = seen[static_cast<std::size_t>(s.network)]++ % n.bus->slots();
      n.reported = s.traffic == Traffic::kSensor;  // a background node only owns its slot
      nodes_.push_back(n);
    }
  }

  void send(int sender, std::uint64_t id, Nanoseconds t) override {
    Node& n = nodes_[static_cast<std::size_t>(sender)];
    serve(sender, t);  // the node's slots up to t first: one starting at t takes this packet
    if (n.waiting.size() >= n.bus->queue()) {
      decided_.push_back(Fate{sender, id, t, Drop::kQueue});
      ++n.counters.dropped[static_cast<int>(Drop::kQueue)];
      return;
    }
    n.waiting.push_back(Packet{id, t});
  }

  void advance_to(Nanoseconds t, std::vector<Fate>& fates) override {
    for (std::size_t s = 0; s < nodes_.size(); ++s) serve(static_cast<int>(s), t);
    std::stable_sort(decided_.begin(), decided_.end(),
                     [](const Fate& a, const Fate& b) { return a.time < b.time; });
    auto due = decided_.begin();
    while (due != decided_.end() && due->time <= t) ++due;
    fates.insert(fates.end(), decided_.begin(), due);
    decided_.erase(decided_.begin(), due);
  }

  // A bus has no positions: the run engine never moves its nodes.
  void move_sender(int, double, double, double, Nanoseconds) override {}
  void move_sink(int, double, double, double, Nanoseconds) override {}

  MacCounters counters(int sender) const override {
    return nodes_[static_cast<std::size_t>(sender)].counters;
  }

 private:
  struct Packet {
    std::uint64_t id;
    Nanoseconds queued;
  };
  struct Node {
    const TdmaDesign* bus = nullptr;
    int slot = 0;
    bool reported = true;
    std::deque<Packet> waiting;
    Nanoseconds next_free = 0;  // no transmission of this node starts before
    MacCounters counters;
  };

  // The first start of node n's slot at or after t: frame f starts at f * slots * slot.
  static Nanoseconds slot_start(const Node& n, Nanoseconds t) {
    const Nanoseconds frame = n.bus->slots() * n.bus->slot();
    const Nanoseconds offset = n.slot * n.bus->slot();
    const Nanoseconds f = t <= offset ? 0 : (t - offset + frame - 1) / frame;
    return f * frame + offset;
  }

  // Node `sender`'s transmissions that start at or before t: each takes its slot, and the sink
  // receives the packet at the slot's end.
  void serve(int sender, Nanoseconds t) {
    Node& n = nodes_[static_cast<std::size_t>(sender)];
    while (!n.waiting.empty()) {
      const Packet& p = n.waiting.front();
      const Nanoseconds start = slot_start(n, std::max(p.queued, n.next_free));
      if (start > t) break;
      ++n.counters.attempts;
      ++n.counters.delivered;
      if (n.reported) decided_.push_back(Fate{sender, p.id, start + n.bus->slot(), Drop::kNone});
      n.next_free = start + n.bus->slot();
      n.waiting.pop_front();
    }
  }

  std::vector<Node> nodes_;
  std::vector<Fate> decided_;
};

class TdmaEngine final : public NetworkEngine {
 public:
  std::string name() const override { return "tdma_bus (examples/tdma_bus)"; }
  std::unique_ptr<NetworkRun> start(const std::vector<const NetworkDesign*>& networks,
                                    const std::vector<Sender>& senders, std::uint64_t,
                                    std::uint64_t) const override {
    std::vector<const TdmaDesign*> buses;
    for (const NetworkDesign* d : networks) buses.push_back(static_cast<const TdmaDesign*>(d));
    return std::make_unique<TdmaRun>(buses, senders);
  }
};

const NetworkEngine& TdmaDesign::engine() const {
  static const TdmaEngine engine;
  return engine;
}

using ncosim::config::Key;

const ncosim::config::Keys& tdma_keys() {
  static const ncosim::config::Keys keys{
      Key::number("slot")
          .range(1e-6, 10.0)
          .says("a slot of 1e-6..10 s")
          .or_default(0.004)
          .unit("s")
          .help("length of one slot: a packet put on the air at a slot's start is received at "
                "its end"),
      Key::integer("slots").range(1, 1024).or_default(2).unit("slots").help(
          "slots per frame; node i owns slot i mod slots of every frame"),
      Key::integer("queue")
          .range(1, 1'000'000)
          .or_default(2)
          .unit("packets")
          .help("packets a node holds that are not yet on the air; one more is dropped (cause "
                "queue)"),
  };
  return keys;
}

std::shared_ptr<const NetworkDesign> read_tdma(const ncosim::config::Table& t) {
  const ncosim::config::KeyReader r(t, tdma_keys());
  return std::make_shared<TdmaDesign>(std::llround(r.number("slot") * 1e9),
                                      static_cast<int>(r.integer("slots")),
                                      static_cast<std::size_t>(r.integer("queue")));
}

}  // namespace

void register_tdma_bus(ncosim::network::NetworkRegistry& registry) {
  registry.add("tdma_bus",
               "time-division bus (examples/tdma_bus): node i owns slot i mod slots of every "
               "frame; a queue per node; no randomness: slot, slots, queue",
               tdma_keys(), read_tdma);
}
