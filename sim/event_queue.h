// sim/event_queue.h — the kernel: a priority queue of events ordered by (time, phase, sequence).
// Within one instant the order is fixed by the phase (plant step, sampling, sending, packet
// arrivals, estimator updates, control, actuation, metrics) and, within a phase, by the order
// of scheduling, so a run never depends on container internals. Scheduling an event in the
// past is a programmer error (NCOSIM_CHECK).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "sim/time.h"

namespace ncosim::sim {

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

  // The earliest pending event (requires !empty()).
  const Event& top() const { return heap_.front(); }

  SimTime now() const { return now_; }
  bool empty() const { return heap_.empty(); }
  std::size_t size() const { return heap_.size(); }
  void reserve(std::size_t n) { heap_.reserve(n); }
  // Drops every pending event and resets the clock and sequence to zero.
  void clear();

 private:
  static bool earlier(const Event& a, const Event& b) {
    // Non-short-circuit form: compiles to flag arithmetic instead of unpredictable branches.
    return (a.time < b.time) | ((a.time == b.time) & (a.key < b.key));
  }
  void sift_up(std::size_t i);
  void sift_down(std::size_t i);

  std::vector<Event> heap_;
  SimTime now_ = 0;
  std::uint64_t seq_ = 0;
};

}  // namespace ncosim::sim
