// sim/event_queue.cc — 4-ary min-heap of events on (time, phase, sequence).
#include "sim/event_queue.h"

#include <utility>

#include "sim/check.h"

namespace ncosim::sim {

namespace {
constexpr int kPhaseShift = 56;
constexpr std::uint64_t kSeqMask = (std::uint64_t{1} << kPhaseShift) - 1;
constexpr std::size_t kArity = 4;
}  // namespace

void EventQueue::schedule(SimTime time, Phase phase, EventHandler* handler, std::uint64_t arg) {
  NCOSIM_CHECK(time >= now_);
  NCOSIM_CHECK(handler != nullptr);
  const std::uint64_t key =
      (static_cast<std::uint64_t>(phase) << kPhaseShift) | (seq_++ & kSeqMask);
  heap_.push_back(Event{time, key, handler, arg});
  sift_up(heap_.size() - 1);
}

bool EventQueue::step() {
  if (heap_.empty()) return false;
  const Event e = heap_.front();
  if (heap_.size() > 1) {
    sift_down(0);
  } else {
    heap_.pop_back();
  }
  now_ = e.time;
  e.handler->handle(e.time, e.arg);
  return true;
}

void EventQueue::run_until(SimTime until) {
  while (!heap_.empty() && heap_.front().time <= until) step();
  if (now_ < until) now_ = until;
}

void EventQueue::clear() {
  heap_.clear();
  now_ = 0;
  seq_ = 0;
}

void EventQueue::sift_up(std::size_t i) {
  Event* h = heap_.data();
  const Event e = h[i];
  while (i > 0) {
    const std::size_t parent = (i - 1) / kArity;
    if (!earlier(e, h[parent])) break;
    h[i] = h[parent];
    i = parent;
  }
  h[i] = e;
}

// Removes h[i] (only called with i = 0): the hole walks down to a leaf along the
// earliest children, then the last event fills it and sifts up (Floyd's bottom-up
// deletion; the last event almost always belongs near the bottom, so this saves one
// comparison per level).
void EventQueue::sift_down(std::size_t i) {
  const Event last = heap_.back();
  heap_.pop_back();
  Event* h = heap_.data();
  const std::size_t n = heap_.size();
  while (true) {
    const std::size_t c = kArity * i + 1;
    std::size_t best;
    if (c + kArity <= n) {
      const std::size_t a = c + static_cast<std::size_t>(earlier(h[c + 1], h[c]));
      const std::size_t b = c + 2 + static_cast<std::size_t>(earlier(h[c + 3], h[c + 2]));
      // Arithmetic select: a ternary here compiles to a branch that mispredicts half the time.
      best = a + (b - a) * static_cast<std::size_t>(earlier(h[b], h[a]));
    } else if (c < n) {
      best = c;
      for (std::size_t k = c + 1; k < n; ++k) {
        if (earlier(h[k], h[best])) best = k;
      }
    } else {
      break;
    }
    h[i] = h[best];
    i = best;
  }
  while (i > 0) {
    const std::size_t parent = (i - 1) / kArity;
    if (!earlier(last, h[parent])) break;
    h[i] = h[parent];
    i = parent;
  }
  h[i] = last;
}

}  // namespace ncosim::sim
