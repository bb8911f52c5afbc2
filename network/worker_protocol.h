// network/worker_protocol.h — the bytes between a run engine and a network worker (internal to
// network/: worker.cc is the caller's side, worker_main.cc the worker's). Every field is a
// kernel/wire.h u64 (little-endian; doubles by their bits, signed integers as two's complement).
//
// Server socket (the caller <-> `EXE network-worker`, its file descriptor 3):
//   caller -> server: 'F' with a socket passed as SCM_RIGHTS: fork a child that serves it.
//   server -> caller: 'X' exit status, then the child's stderr and stdout (a string, its last MB)
//                     once that child has ended; nothing else.
// Run socket (the caller <-> the child):
//   'I' seed run, networks (count, then kind and table strings), senders (count, then
//       kSenderWords each): the child replies 'R' (ready) or 'E' message (it cannot build them;
//       it then exits).
//   'S' sender id t; 'M' sender x y z t; 'N' network x y z t: no reply.
//   'A' t: the child replies 'F' count, then per fate: sender id time drop.
//   'C': the child replies 'K' count, then per sender: delivered attempts retries busy_ns and
//       the drops by cause (kCounterWords in all).
//   End of file: the child exits 0.
#pragma once

#include <bit>
#include <cstdint>
#include <string>

#include "kernel/wire.h"
#include "network/backend.h"

namespace ncosim::network::wire {

inline constexpr std::size_t kSenderWords = 10;
inline constexpr std::size_t kFateWords = 4;
inline constexpr std::size_t kCounterWords = 4 + kDropCauses;

inline void put_double(std::string& out, double v) {
  kernel::put_u64(out, std::bit_cast<std::uint64_t>(v));
}
inline void put_i64(std::string& out, std::int64_t v) {
  kernel::put_u64(out, static_cast<std::uint64_t>(v));
}
inline double get_double(const char* p) { return std::bit_cast<double>(kernel::get_u64(p)); }
inline std::int64_t get_i64(const char* p) { return static_cast<std::int64_t>(kernel::get_u64(p)); }

inline void put_sender(std::string& out, const Sender& s) {
  put_i64(out, s.network);
  kernel::put_u64(out, s.bytes);
  put_double(out, s.x);
  put_double(out, s.y);
  put_double(out, s.z);
  kernel::put_u64(out, static_cast<std::uint64_t>(s.traffic));
  put_i64(out, s.vehicle);
  put_double(out, s.rate);
  kernel::put_u64(out, s.downlink ? 1 : 0);
  kernel::put_u64(out, 0);  // reserved
}
inline Sender get_sender(const char* p) {
  Sender s;
  s.network = static_cast<int>(get_i64(p));
  s.bytes = static_cast<std::uint32_t>(kernel::get_u64(p + 8));
  s.x = get_double(p + 16);
  s.y = get_double(p + 24);
  s.z = get_double(p + 32);
  s.traffic = static_cast<Traffic>(kernel::get_u64(p + 40));
  s.vehicle = static_cast<int>(get_i64(p + 48));
  s.rate = get_double(p + 56);
  s.downlink = kernel::get_u64(p + 64) != 0;
  return s;
}

inline void put_counters(std::string& out, const MacCounters& c) {
  kernel::put_u64(out, c.delivered);
  kernel::put_u64(out, c.attempts);
  kernel::put_u64(out, c.retries);
  put_i64(out, c.busy_ns);
  for (const std::uint64_t d : c.dropped) kernel::put_u64(out, d);
}
inline MacCounters get_counters(const char* p) {
  MacCounters c;
  c.delivered = kernel::get_u64(p);
  c.attempts = kernel::get_u64(p + 8);
  c.retries = kernel::get_u64(p + 16);
  c.busy_ns = get_i64(p + 24);
  for (std::size_t d = 0; d < kDropCauses; ++d) c.dropped[d] = kernel::get_u64(p + 32 + 8 * d);
  return c;
}

}  // namespace ncosim::network::wire
