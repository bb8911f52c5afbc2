// kernel/rng.h — random streams: one Boost.Random engine per (campaign seed, run, component).
// Boost.Random engines and distributions give the same numbers on every platform and
// compiler (the standard library's distributions do not), so a run is a pure function
// of (scenario, seed, run index) whatever the thread count.
#pragma once

#include <boost/random/mersenne_twister.hpp>
#include <cstdint>

namespace ncosim::kernel {

using Rng = boost::random::mt19937_64;

// SplitMix64 finaliser (Steele, Lea & Flood 2014): a bijective 64-bit mixer.
constexpr std::uint64_t splitmix64(std::uint64_t z) {
  z += 0x9E3779B97F4A7C15ULL;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  return z ^ (z >> 31);
}

// Stable component identifiers: a stream id is (kind << 32) | index.
enum class StreamKind : std::uint64_t {
  kPlant = 1,
  kSensor = 2,
  kLink = 3,
  kInput = 4,
  kActuatorLink = 5,
  kEstimator = 6,
  kNetwork = 7,  // ns-3's generator of a run's networks (network/)
};

constexpr std::uint64_t stream_id(StreamKind kind, std::uint64_t index) {
  return (static_cast<std::uint64_t>(kind) << 32) | index;
}

// The engine of one component in one run. Streams of different (seed, run, component)
// triples are seeded from distinct 64-bit mixes.
inline Rng make_stream(std::uint64_t seed, std::uint64_t run, std::uint64_t component) {
  const std::uint64_t s = splitmix64(splitmix64(splitmix64(seed) ^ run) ^ component);
  return Rng(s);
}

}  // namespace ncosim::kernel
