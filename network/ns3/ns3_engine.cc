// network/ns3/ns3_engine.cc — the ns-3 engine (builds with ns-3): a run's ns-3 networks built into
// one World (network/ns3/world.h) and the lockstep that keeps ns-3 behind ncosim's clock
// (network/backend.h, NetworkRun).
#include <ns3/fatal-error.h>
#include <ns3/mac48-address.h>
#include <ns3/rng-seed-manager.h>
#include <ns3/simulator.h>

#include <cstdlib>
#include <mutex>
#include <string>

#include "kernel/check.h"
#include "network/ns3/world.h"

namespace ncosim::network {

namespace {

// ns-3 has one simulator per process: one session at a time.
std::mutex& simulator_mutex() {
  static std::mutex m;
  return m;
}

class Ns3Run final : public NetworkRun {
 public:
  Ns3Run(const std::vector<const NetworkDesign*>& designs, const std::vector<Sender>& senders,
         std::uint64_t seed, std::uint64_t run)
      : lock_(simulator_mutex()), world_(senders) {
    // ns-3's generator (MRG32k3a): its seed from the campaign seed, its run (sub-stream) the
    // run index, so that a run's network is the same whatever process, thread or shard runs it.
    ns3::RngSeedManager::SetSeed(ns3_seed(seed));
    ns3::RngSeedManager::SetRun(run);
    ns3::Mac48Address::ResetAllocationIndex();  // the same addresses in every run
    for (std::size_t n = 0; n < designs.size(); ++n) {
      std::vector<int> attached;
      for (std::size_t s = 0; s < senders.size(); ++s) {
        if (senders[s].network == static_cast<int>(n)) attached.push_back(static_cast<int>(s));
      }
      world_.building(static_cast<int>(n));
      // Every design of this engine is an ns-3 kind (Ns3Network::engine).
      static_cast<const Ns3Network*>(designs[n])->build(world_, attached);
    }
    world_.start_traffic();
    schedule_test_crash(run);
  }
  ~Ns3Run() override { ns3::Simulator::Destroy(); }

  void send(int sender, std::uint64_t id, Nanoseconds t) override {
    const std::int64_t now = ns3::Simulator::Now().GetNanoSeconds();
    NCOSIM_CHECK(t >= now);
    ns3::Simulator::Schedule(ns3::NanoSeconds(t - now), &World::send_now, &world_, sender, id);
  }

  // Every event at times <= t: an event at t checks, once every event already at t has run,
  // whether any ran since its previous check (those may have scheduled more at t); when none
  // did, no event at t is left and ns-3 stops at t.
  void advance_to(Nanoseconds t, std::vector<Fate>& fates) override {
    const std::int64_t now = ns3::Simulator::Now().GetNanoSeconds();
    NCOSIM_CHECK(t >= now);
    world_.collect_into(&fates);
    last_check_ = ~std::uint64_t{0};
    ns3::Simulator::Schedule(ns3::NanoSeconds(t - now), &Ns3Run::check, this);
    ns3::Simulator::Run();
    world_.collect_into(nullptr);
  }

  void move_sender(int sender, double x, double y, double z, Nanoseconds t) override {
    move(world_.sender_mobility(sender), x, y, z, t);
  }
  void move_sink(int network, double x, double y, double z, Nanoseconds t) override {
    move(world_.sink_mobility(network), x, y, z, t);
  }

  MacCounters counters(int sender) const override { return world_.counters(sender); }

 private:
  static void place(ns3::Ptr<ns3::MobilityModel> m, ns3::Vector p) { m->SetPosition(p); }
  void move(const ns3::Ptr<ns3::MobilityModel>& m, double x, double y, double z, Nanoseconds t) {
    NCOSIM_CHECK(m != nullptr);  // the reader refuses a vehicle on a kind without positions
    const std::int64_t now = ns3::Simulator::Now().GetNanoSeconds();
    NCOSIM_CHECK(t >= now);
    ns3::Simulator::Schedule(ns3::NanoSeconds(t - now), &Ns3Run::place, m, ns3::Vector(x, y, z));
  }

  // A test hook, for tests only: with NCOSIM_TEST_CRASH_RUN=<run index> in the environment, that
  // run's ns-3 fails an NS_FATAL_ERROR inside Simulator::Run (its first event), so that the tests
  // of a crashing run (tests/network/network_test.cc) go through ns-3's own fatal-error path.
  static void schedule_test_crash(std::uint64_t run) {
    const char* v = std::getenv("NCOSIM_TEST_CRASH_RUN");
    if (v == nullptr || std::to_string(run) != v) return;
    ns3::Simulator::ScheduleNow(
        +[](std::uint64_t r) { NS_FATAL_ERROR("NCOSIM_TEST_CRASH_RUN: run " << r << " fails"); },
        run);
  }

  void check() {
    const std::uint64_t count = ns3::Simulator::GetEventCount();
    if (count == last_check_ + 1) {
      ns3::Simulator::Stop();
      return;
    }
    last_check_ = count;
    ns3::Simulator::ScheduleNow(&Ns3Run::check, this);
  }

  std::unique_lock<std::mutex> lock_;
  World world_;
  std::uint64_t last_check_ = 0;
};

class Ns3Engine final : public NetworkEngine {
 public:
  std::string name() const override { return "ns-3"; }
  bool needs_own_process() const override { return true; }
  std::unique_ptr<NetworkRun> start(const std::vector<const NetworkDesign*>& networks,
                                    const std::vector<Sender>& senders, std::uint64_t seed,
                                    std::uint64_t run) const override {
    return std::make_unique<Ns3Run>(networks, senders, seed, run);
  }
};

}  // namespace

const NetworkEngine& ns3_engine() {
  static const Ns3Engine engine;
  return engine;
}

bool have_ns3() { return true; }

}  // namespace ncosim::network
