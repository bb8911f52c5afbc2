// tests/network/network_fixtures.h — what the network tests share: a [[network]] table read by its
// kind's reader, a session advanced to an instant, and ten nodes sending bursts at once.
#pragma once

#include <toml++/toml.h>

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "config/config.h"
#include "network/network.h"
#include "network/networks.h"
#include "sim/scenario/registries.h"

namespace ncosim::network::testing {

inline constexpr std::int64_t kMs = 1'000'000;

// A [[network]] table read by its kind's reader, as the scenario reader does; kept alive until the
// test program ends (a run's callbacks hold its design, as a scenario holds its networks).
inline std::shared_ptr<const NetworkDesign> design(const std::string& table) {
  static std::vector<toml::table> docs;  // kept alive as the scenario reader keeps its document
  static std::vector<std::shared_ptr<const NetworkDesign>> designs;
  docs.push_back(toml::parse(table));
  const config::Table t(docs.back(), "network[0]", "test.toml");
  designs.push_back(sim::network_registry().lookup(t, "kind", "").factory(t));
  return designs.back();
}

// A run of `designs` in this process (network::start_here).
inline std::unique_ptr<NetworkRun> start(
    const std::vector<std::shared_ptr<const NetworkDesign>>& designs,
    const std::vector<Sender>& senders, std::uint64_t seed, std::uint64_t run) {
  std::vector<const NetworkDesign*> d;
  for (const auto& x : designs) d.push_back(x.get());
  return start_here(d, senders, seed, run);
}

// The fates reported up to `t` (ns).
inline std::vector<Fate> advance(NetworkRun& s, std::int64_t t) {
  std::vector<Fate> f;
  s.advance_to(t, f);
  return f;
}

// Ten nodes 5..14 m from the sink of `table` send a packet of `bytes` at the same instant, five
// times 50 ms apart; every fate up to 1 s of run `run` (seed 3).
inline std::vector<Fate> burst(const std::string& table, std::uint32_t bytes, std::uint64_t run) {
  std::vector<Sender> senders;
  for (int n = 0; n < 10; ++n) senders.push_back(Sender{0, bytes, 5.0 + n, 3.0, 0.0});
  auto s = start({design(table)}, senders, 3, run);
  std::vector<Fate> all;
  for (int k = 0; k < 5; ++k) {
    for (int n = 0; n < 10; ++n) s->send(n, static_cast<std::uint64_t>(10 * k + n), k * 50 * kMs);
    s->advance_to(k * 50 * kMs, all);
  }
  s->advance_to(1000 * kMs, all);
  return all;
}

}  // namespace ncosim::network::testing
