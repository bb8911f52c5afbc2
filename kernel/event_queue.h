// kernel/event_queue.h — the kernel: a priority queue of events ordered by (time, phase, sequence).
// Within one instant the order is fixed by the phase (plant step, sampling, sending, packet
// arrivals, estimator updates, control, actuation, metrics) and, within a phase, by the order
// of scheduling, so a run never depends on container internals. Scheduling an event in the
// past is a programmer error (NCOSIM_CHECK).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "kernel/time.h"

namespace ncosim::kernel {

// Phases at one instant, in dispatch order.
enum class Phase : std::uint8_t {
  kPlant = 0,     // plant step x[k] = A x[k-1] + ...
  kSample = 1,    // sensors sample y[k]
  kSend = 2,      // packets handed to their links
  kArrival = 3,   // packets delivered to the estimators
  kEstimate = 4,  // estimator period updates
  kControl = 5,   // controllers compute u[k]
  kActuate = 6,   // actuator links deliver u[k] to the plant
  kMetrics = 7,   // errors recorded
};
inline constexpr int kPhaseCount = 8;

// Receiver of events. `arg` is the 64-bit payload given at scheduling time.
class EventHandler {
 public:
  virtual ~EventHandler() = default;
  virtual void handle(SimTime now, std::uint64_t arg) = 0;
};

// Pending events wait in a radix heap on time (Ahuja, Mehlhorn, Orlin & Tarjan 1990, "Faster
// algorithms for the shortest path problem", J. ACM 37(2), section 3, with base-32 digits
// instead of bits). An event sits in bucket (d, v): d is the highest base-32 digit in which
// its time differs from base_, the last dispatched time, and v is its own value of that
// digit. Lower buckets hold earlier times; since nothing is scheduled before now(), an event
// only ever moves down, when its bucket is the earliest: at most 13 moves, 2.9 on average in
// bench/kernel_bench.cc. The events at time base_ form a binary heap on (phase, sequence).
// Buckets are chains of 16-event blocks from one pool, so memory follows the pending count.
class EventQueue {
 public:
  struct Event {
    SimTime time;
    std::uint64_t key;  // phase in the top 8 bits, insertion sequence below
    EventHandler* handler;
    std::uint64_t arg;
  };

  EventQueue() = default;

  // Schedules handler->handle(time, arg) at (time, phase). Requires time >= now().
  void schedule(SimTime time, Phase phase, EventHandler* handler, std::uint64_t arg = 0);

  // Dispatches the earliest event. Returns false when the queue is empty.
  bool step();

  // Dispatches every event with time <= until, in order; now() becomes `until` if the
  // queue was drained up to it.
  void run_until(SimTime until);

  // The earliest pending event (requires !empty()); valid until the next non-const call.
  // O(1) while events remain at the current instant, otherwise a scan of one bucket.
  const Event& top() const;

  SimTime now() const { return now_; }
  bool empty() const { return size_ == 0; }
  std::size_t size() const { return size_; }
  // Preallocates storage for n pending events.
  void reserve(std::size_t n);
  // Drops every pending event and resets the clock and sequence to zero.
  void clear();

 private:
  static constexpr int kDigitBits = 5;
  static constexpr int kRadix = 1 << kDigitBits;
  static constexpr int kDigits = (63 + kDigitBits - 1) / kDigitBits;  // times are in [0, 2^63)
  static_assert(kRadix <= 32 && kDigits <= 32, "occupancy masks are 32-bit");
  static constexpr std::uint32_t kBlockEvents = 16;  // 512-byte blocks
  static constexpr std::uint32_t kNoBlock = ~std::uint32_t{0};

  // A chain of blocks linked by next_; the head block holds `fill` events, the others are
  // full. An emptied bucket keeps its head block for its next events.
  struct Bucket {
    std::uint32_t head = kNoBlock;
    std::uint32_t fill = kBlockEvents;  // no head block: the next push takes one
  };

  Event& slot(std::uint32_t block, std::uint32_t i) {
    return slots_[std::size_t{block} * kBlockEvents + i];
  }
  const Event& slot(std::uint32_t block, std::uint32_t i) const {
    return slots_[std::size_t{block} * kBlockEvents + i];
  }
  std::uint32_t take_block();
  void push(Bucket& bucket, const Event& e);
  void empty_bucket(int b);
  void place(const Event& e);
  int lowest_bucket() const;
  SimTime bucket_min(int b) const;
  void refill(int b, SimTime m);
  void dispatch(const Event& e);

  // The pool: block i is slots_[i * kBlockEvents, (i + 1) * kBlockEvents); next_[i] is the
  // next block of its bucket or of the free list (kNoBlock ends both).
  std::vector<Event> slots_;
  std::vector<std::uint32_t> next_;
  std::uint32_t free_ = kNoBlock;
  std::array<Bucket, kDigits * kRadix> buckets_{};  // bucket (d, v) is buckets_[d * kRadix + v]
  std::array<std::uint32_t, kDigits> occupied_{};   // bit v of [d]: bucket (d, v) non-empty
  std::uint32_t digits_ = 0;                        // bit d: occupied_[d] != 0
  std::vector<Event> current_;  // the events at time base_, a binary min-heap on key
  std::size_t size_ = 0;
  SimTime base_ = 0;  // the last dispatched time (0 at first); <= every pending time
  SimTime now_ = 0;
  std::uint64_t seq_ = 0;
};

}  // namespace ncosim::kernel
