// tests/kernel/event_queue_test.cc — EventQueue: dispatch order against a sorted reference, phase
// order, FIFO ties, run_until, clear, size, and the abort on scheduling in the past.
#include "kernel/event_queue.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "kernel/time.h"

namespace ncosim::kernel {
namespace {

// One dispatch as seen by a handler.
struct Dispatch {
  SimTime time;
  Phase phase;
  std::uint64_t id;
  friend bool operator==(const Dispatch&, const Dispatch&) = default;
};

std::string describe(const Dispatch& d) {
  std::ostringstream s;
  s << "(t=" << d.time << ", phase=" << static_cast<int>(d.phase) << ", id=" << d.id << ")";
  return s.str();
}

// Empty string when equal, else the first index where the two logs differ.
std::string first_difference(const std::vector<Dispatch>& got, const std::vector<Dispatch>& want) {
  const std::size_t n = std::min(got.size(), want.size());
  for (std::size_t i = 0; i < n; ++i) {
    if (!(got[i] == want[i])) {
      return "dispatch #" + std::to_string(i) + ": got " + describe(got[i]) + ", want " +
             describe(want[i]);
    }
  }
  if (got.size() != want.size()) {
    return "lengths differ: got " + std::to_string(got.size()) + ", want " +
           std::to_string(want.size());
  }
  return "";
}

// Records (now, arg) for every dispatch and checks that now() agrees with the handler's time.
class Recorder final : public EventHandler {
 public:
  explicit Recorder(const EventQueue* queue) : queue_(queue) {}
  void handle(SimTime now, std::uint64_t arg) override {
    EXPECT_EQ(queue_->now(), now) << "arg " << arg;
    log.emplace_back(now, arg);
  }
  std::vector<std::pair<SimTime, std::uint64_t>> log;

 private:
  const EventQueue* queue_;
};

// ---------------------------------------------------------------------------------------------
// Reference model: a std::set ordered by (time, phase, insertion sequence), i.e. the order the
// kernel promises, obtained by sorting rather than by a heap.

class ReferenceQueue {
 public:
  struct Entry {
    SimTime time;
    Phase phase;
    std::uint64_t seq;
    EventHandler* handler;
    std::uint64_t arg;
    bool operator<(const Entry& o) const {
      return std::tie(time, phase, seq) < std::tie(o.time, o.phase, o.seq);
    }
  };

  void schedule(SimTime time, Phase phase, EventHandler* handler, std::uint64_t arg) {
    ASSERT_GE(time, now_);
    pending_.insert(Entry{time, phase, seq_++, handler, arg});
  }
  bool step() {
    if (pending_.empty()) return false;
    const Entry e = *pending_.begin();
    pending_.erase(pending_.begin());
    now_ = e.time;
    e.handler->handle(e.time, e.arg);
    return true;
  }
  void run_until(SimTime until) {
    while (!pending_.empty() && pending_.begin()->time <= until) step();
    if (now_ < until) now_ = until;
  }
  const Entry& top() const { return *pending_.begin(); }
  SimTime now() const { return now_; }
  std::size_t size() const { return pending_.size(); }
  bool empty() const { return pending_.empty(); }

 private:
  std::set<Entry> pending_;
  SimTime now_ = 0;
  std::uint64_t seq_ = 0;
};

// SplitMix64 finaliser: the behaviour of event `id` is a pure function of (seed, id), so the
// queue under test and the reference spawn the same children whatever order they dispatch in.
std::uint64_t mix(std::uint64_t z) {
  z += 0x9E3779B97F4A7C15ULL;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  return z ^ (z >> 31);
}

// Offsets skewed towards ties: half are 0 (same instant), most others a few ns, a few span
// up to 2^40 ns so that times differ in high bits too.
SimTime draw_offset(std::uint64_t r) {
  const std::uint64_t u = r % 100;
  const std::uint64_t v = r >> 8;
  if (u < 50) return 0;
  if (u < 85) return static_cast<SimTime>(1 + v % 4);
  if (u < 97) return static_cast<SimTime>(v % 1000);
  return static_cast<SimTime>(v % (std::uint64_t{1} << 40));
}

// Each dispatched event logs itself and schedules 0, 1 or 2 children at now + offset in a
// random phase (any phase, also one earlier than its own), until `cap` events exist.
// With `causal`, a child is never earlier than its parent in (time, phase) order.
template <class Queue>
class Spawner final : public EventHandler {
 public:
  Spawner(Queue* queue, std::uint64_t seed, std::uint64_t cap, bool causal)
      : queue_(queue), seed_(seed), cap_(cap), causal_(causal) {}

  void handle(SimTime now, std::uint64_t arg) override {
    const Phase phase = phase_of_[arg];
    EXPECT_EQ(queue_->now(), now);
    log.push_back(Dispatch{now, phase, arg});
    const std::uint64_t r = mix(seed_ ^ mix(arg));
    const int children = static_cast<int>(r % 3);
    for (int c = 0; c < children; ++c) {
      const std::uint64_t rc = mix(r + static_cast<std::uint64_t>(c) + 1);
      SimTime offset = draw_offset(rc);
      auto child_phase = static_cast<Phase>((rc >> 40) % kPhaseCount);
      if (causal_ && offset == 0 && child_phase < phase) child_phase = phase;
      schedule(now + offset, child_phase);
    }
  }

  // Schedules a new event (from inside a handler or from the driver).
  void schedule(SimTime time, Phase phase) {
    if (next_id_ >= cap_) return;
    phase_of_.push_back(phase);
    queue_->schedule(time, phase, this, next_id_++);
  }

  std::vector<Dispatch> log;

 private:
  Queue* queue_;
  std::uint64_t seed_;
  std::uint64_t cap_;
  bool causal_;
  std::uint64_t next_id_ = 0;
  std::vector<Phase> phase_of_;
};

// Drives a queue through a seeded script: initial events with many ties, then a mix of
// step(), run_until() and schedules from outside handlers. Before every step() it checks that
// top() is the event that step() dispatches. Returns the dispatch log.
template <class Queue>
std::vector<Dispatch> run_script(std::uint64_t seed, bool causal) {
  constexpr std::uint64_t kCap = 20'000;
  Queue queue;
  Spawner<Queue> spawner(&queue, seed, kCap, causal);
  std::mt19937_64 rng(seed);
  // 400 initial events on 40 instants x 8 phases: about 1.25 per (time, phase) pair.
  for (int i = 0; i < 400; ++i) {
    spawner.schedule(static_cast<SimTime>(rng() % 40), static_cast<Phase>(rng() % kPhaseCount));
  }
  while (!queue.empty()) {
    const std::uint64_t op = rng() % 10;
    if (op < 6) {
      const std::uint64_t expected = queue.top().arg;
      const SimTime expected_time = queue.top().time;
      queue.step();
      EXPECT_EQ(spawner.log.back().id, expected) << "top() disagrees with step()";
      EXPECT_EQ(spawner.log.back().time, expected_time);
    } else if (op < 9) {
      queue.run_until(queue.now() + draw_offset(rng()));
    } else if (!causal) {
      spawner.schedule(queue.now() + draw_offset(rng()), static_cast<Phase>(rng() % kPhaseCount));
    }
  }
  return spawner.log;
}

// Number of dispatches that share (time, phase) with their predecessor: the FIFO rule decides
// their order, so the conformance checks below are only meaningful if this is large.
std::size_t tie_count(const std::vector<Dispatch>& log) {
  std::size_t ties = 0;
  for (std::size_t i = 1; i < log.size(); ++i) {
    ties += log[i].time == log[i - 1].time && log[i].phase == log[i - 1].phase;
  }
  return ties;
}

constexpr std::uint64_t kSeeds[] = {1, 2, 3, 42, 2024, 0xDEADBEEF, 987654321, 31337};

// Any phase may be scheduled at the current instant, so later dispatches can precede earlier
// ones in (time, phase) order; the reference replays the same script on a sorted set, and the
// two logs must be identical event by event.
TEST(EventQueue, RandomSchedulesDispatchInTheSameOrderAsASortedReference) {
  for (const std::uint64_t seed : kSeeds) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    const std::vector<Dispatch> got = run_script<EventQueue>(seed, /*causal=*/false);
    const std::vector<Dispatch> want = run_script<ReferenceQueue>(seed, /*causal=*/false);
    // 20'000 events are created (the cap), and every one is dispatched exactly once.
    ASSERT_EQ(want.size(), 20'000u);
    EXPECT_EQ(first_difference(got, want), "");
    // Half of the offsets are 0, so many dispatches tie in (time, phase) with the previous
    // one (2596 to 3803 over these seeds); require 1000 so FIFO is exercised on every seed.
    EXPECT_GE(tie_count(want), 1000u) << "script does not exercise FIFO ties";
  }
}

// When no event is scheduled before its parent in (time, phase) order, the whole dispatch log
// is simply every scheduled event sorted by (time, phase, insertion order): no replay needed.
TEST(EventQueue, CausalSchedulesDispatchInGloballySortedOrder) {
  for (const std::uint64_t seed : kSeeds) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    const std::vector<Dispatch> got = run_script<EventQueue>(seed, /*causal=*/true);
    ASSERT_EQ(got.size(), 20'000u);
    // Ids are assigned in scheduling order, so (time, phase, id) is (time, phase, sequence).
    std::vector<Dispatch> want = got;
    std::sort(want.begin(), want.end(), [](const Dispatch& a, const Dispatch& b) {
      return std::tie(a.time, a.phase, a.id) < std::tie(b.time, b.phase, b.id);
    });
    EXPECT_EQ(first_difference(got, want), "");
    EXPECT_GE(tie_count(want), 1000u);  // 8271 to 10075 over these seeds
  }
}

// ---------------------------------------------------------------------------------------------
// Targeted cases.

// Eight events at t = 5 scheduled in reverse phase order, bracketed by a kMetrics event at
// t = 4 and a kPlant event at t = 6: time dominates phase, then phases run in enum order.
// Expected args: 100 (t=4), 0..7 (t=5, kPlant..kMetrics), 200 (t=6).
TEST(EventQueue, PhasesDispatchInEnumOrderWithinOneInstant) {
  EventQueue queue;
  Recorder rec(&queue);
  queue.schedule(6, Phase::kPlant, &rec, 200);
  for (int p = kPhaseCount - 1; p >= 0; --p) {
    queue.schedule(5, static_cast<Phase>(p), &rec, static_cast<std::uint64_t>(p));
  }
  queue.schedule(4, Phase::kMetrics, &rec, 100);
  while (queue.step()) {
  }
  const std::vector<std::pair<SimTime, std::uint64_t>> want = {
      {4, 100}, {5, 0}, {5, 1}, {5, 2}, {5, 3}, {5, 4}, {5, 5}, {5, 6}, {5, 7}, {6, 200}};
  EXPECT_EQ(rec.log, want);
}

// 1000 events at (t = 7, kArrival) interleaved with events of other phases and times: the
// kArrival ones come out in scheduling order, args 0, 1, ..., 999 (a heap without the
// sequence tie-break reorders equal keys long before 1000).
TEST(EventQueue, EqualTimeAndPhaseDispatchInSchedulingOrder) {
  EventQueue queue;
  Recorder rec(&queue);
  constexpr std::uint64_t kN = 1000;
  constexpr std::uint64_t kOther = 1'000'000;
  for (std::uint64_t i = 0; i < kN; ++i) {
    queue.schedule(7, Phase::kArrival, &rec, i);
    queue.schedule(static_cast<SimTime>(i % 13), static_cast<Phase>(i % kPhaseCount), &rec,
                   kOther + i);
  }
  while (queue.step()) {
  }
  std::vector<std::uint64_t> arrivals;
  for (const auto& [t, arg] : rec.log) {
    if (arg < kOther) {
      EXPECT_EQ(t, 7);
      arrivals.push_back(arg);
    }
  }
  ASSERT_EQ(arrivals.size(), kN);
  for (std::uint64_t i = 0; i < kN; ++i) {
    ASSERT_EQ(arrivals[i], i) << "FIFO broken at position " << i;
  }
}

// Handler that schedules a fixed list of follow-ups the first time it runs.
class FollowUp final : public EventHandler {
 public:
  struct Item {
    SimTime time;
    Phase phase;
    std::uint64_t arg;
  };
  FollowUp(EventQueue* queue, EventHandler* target, std::vector<Item> items)
      : queue_(queue), target_(target), items_(std::move(items)) {}
  void handle(SimTime, std::uint64_t) override {
    for (const Item& it : items_) queue_->schedule(it.time, it.phase, target_, it.arg);
    items_.clear();
  }

 private:
  EventQueue* queue_;
  EventHandler* target_;
  std::vector<Item> items_;
};

// A handler at (t = 10, kSend) schedules (10, kSend) and (10, kPlant). Pending before it:
// (10, kSend) arg 1 and (10, kMetrics) arg 2. The new kSend event queues behind the pending
// kSend one (FIFO), while the kPlant event is the earliest pending event in (time, phase) order
// and therefore runs next, although kPlant "has passed" at t = 10.
// Expected args: 3 (kPlant), 1 (old kSend), 4 (new kSend), 2 (kMetrics).
TEST(EventQueue, EventScheduledFromHandlerAtCurrentInstantTakesItsPlaceByPhase) {
  EventQueue queue;
  Recorder rec(&queue);
  FollowUp trigger(&queue, &rec, {{10, Phase::kSend, 4}, {10, Phase::kPlant, 3}});
  queue.schedule(10, Phase::kSend, &trigger);
  queue.schedule(10, Phase::kSend, &rec, 1);
  queue.schedule(10, Phase::kMetrics, &rec, 2);
  while (queue.step()) {
  }
  const std::vector<std::pair<SimTime, std::uint64_t>> want = {{10, 3}, {10, 1}, {10, 4}, {10, 2}};
  EXPECT_EQ(rec.log, want);
}

// Times far apart in magnitude (0 .. INT64_MAX) dispatch in numeric order: args 0..7.
TEST(EventQueue, TimesSpanningTheWholeRangeDispatchInNumericOrder) {
  constexpr SimTime kMax = std::numeric_limits<SimTime>::max();
  const std::vector<SimTime> times = {
      0,
      1,
      1 << 20,
      (SimTime{1} << 32) - 1,
      SimTime{1} << 32,
      SimTime{1} << 40,
      SimTime{1} << 62,
      kMax,
  };
  EventQueue queue;
  Recorder rec(&queue);
  for (std::size_t i : {5, 2, 7, 0, 6, 3, 1, 4}) queue.schedule(times[i], Phase::kPlant, &rec, i);
  while (queue.step()) {
  }
  ASSERT_EQ(rec.log.size(), times.size());
  for (std::size_t i = 0; i < times.size(); ++i) {
    EXPECT_EQ(rec.log[i], std::make_pair(times[i], std::uint64_t{i}));
  }
}

// Events at 10, 20, 20, 30; the handler of the one at 10 adds one at 15 and one at 20 (both
// <= 20). run_until(20) dispatches 10, 15, 20, 20, 20 (events exactly at `until` included),
// leaves 30 pending and sets now() = 20. run_until(25) dispatches nothing and sets now() = 25;
// run_until(24) then leaves now() at 25 (the clock never goes back). run_until(100) dispatches
// 30 and sets now() = 100.
TEST(EventQueue, RunUntilDispatchesEventsUpToAndIncludingUntilThenSetsClock) {
  EventQueue queue;
  Recorder rec(&queue);
  FollowUp trigger(&queue, &rec, {{15, Phase::kPlant, 15}, {20, Phase::kMetrics, 21}});
  queue.schedule(10, Phase::kPlant, &trigger);
  queue.schedule(20, Phase::kPlant, &rec, 20);
  queue.schedule(20, Phase::kSample, &rec, 22);
  queue.schedule(30, Phase::kPlant, &rec, 30);

  queue.run_until(20);
  const std::vector<std::pair<SimTime, std::uint64_t>> want = {
      {15, 15}, {20, 20}, {20, 22}, {20, 21}};  // trigger (t = 10) is not a Recorder
  EXPECT_EQ(rec.log, want);
  EXPECT_EQ(queue.now(), 20);
  EXPECT_EQ(queue.size(), 1u);

  queue.run_until(25);
  EXPECT_EQ(rec.log.size(), 4u);
  EXPECT_EQ(queue.now(), 25);
  queue.run_until(24);
  EXPECT_EQ(queue.now(), 25);
  EXPECT_EQ(queue.size(), 1u);

  queue.run_until(100);
  ASSERT_EQ(rec.log.size(), 5u);
  EXPECT_EQ(rec.log.back(), std::make_pair(SimTime{30}, std::uint64_t{30}));
  EXPECT_EQ(queue.now(), 100);
  EXPECT_TRUE(queue.empty());
}

// After run_until(50) on an empty queue, scheduling at exactly 50 is allowed and dispatches
// at 50.
TEST(EventQueue, RunUntilOnEmptyQueueAdvancesClockToUntil) {
  EventQueue queue;
  Recorder rec(&queue);
  queue.run_until(50);
  EXPECT_EQ(queue.now(), 50);
  queue.schedule(50, Phase::kPlant, &rec, 1);
  EXPECT_TRUE(queue.step());
  EXPECT_EQ(rec.log, (std::vector<std::pair<SimTime, std::uint64_t>>{{50, 1}}));
}

// size() counts pending events: +1 per schedule, -1 per step (a handler's own schedules count
// once they are made). step() on an empty queue returns false and changes nothing.
TEST(EventQueue, SizeAndEmptyCountPendingEvents) {
  EventQueue queue;
  Recorder rec(&queue);
  EXPECT_TRUE(queue.empty());
  EXPECT_EQ(queue.size(), 0u);
  EXPECT_FALSE(queue.step());
  EXPECT_EQ(queue.now(), 0);
  for (std::uint64_t i = 0; i < 5; ++i) {
    queue.schedule(static_cast<SimTime>(10 - i), Phase::kPlant, &rec, i);
    EXPECT_EQ(queue.size(), i + 1);
  }
  EXPECT_FALSE(queue.empty());
  EXPECT_EQ(queue.top().time, 6);  // earliest of 10, 9, 8, 7, 6
  EXPECT_EQ(queue.top().arg, 4u);
  for (std::size_t left = 4; queue.step(); --left) EXPECT_EQ(queue.size(), left);
  EXPECT_TRUE(queue.empty());
  EXPECT_EQ(queue.now(), 10);
  EXPECT_EQ(rec.log.size(), 5u);
}

// clear() at now = 30 with two events pending: both are dropped (never dispatched), the clock
// returns to 0 (so t = 0 can be scheduled again) and FIFO order holds afresh.
TEST(EventQueue, ClearDropsPendingEventsAndResetsClock) {
  EventQueue queue;
  Recorder rec(&queue);
  queue.schedule(30, Phase::kPlant, &rec, 1);
  queue.schedule(40, Phase::kPlant, &rec, 2);
  queue.schedule(50, Phase::kPlant, &rec, 3);
  ASSERT_TRUE(queue.step());
  ASSERT_EQ(queue.now(), 30);

  queue.clear();
  EXPECT_TRUE(queue.empty());
  EXPECT_EQ(queue.size(), 0u);
  EXPECT_EQ(queue.now(), 0);
  EXPECT_FALSE(queue.step());

  queue.schedule(0, Phase::kSend, &rec, 10);
  queue.schedule(0, Phase::kSend, &rec, 11);
  queue.schedule(0, Phase::kPlant, &rec, 12);
  while (queue.step()) {
  }
  const std::vector<std::pair<SimTime, std::uint64_t>> want = {{30, 1}, {0, 12}, {0, 10}, {0, 11}};
  EXPECT_EQ(rec.log, want);
}

// Scheduling before now() is a programmer error: NCOSIM_CHECK prints the failed condition and
// aborts, after step() and after run_until() alike; a null handler aborts too.
TEST(EventQueueDeathTest, SchedulingInThePastAborts) {
  EventQueue queue;
  Recorder rec(&queue);
  queue.schedule(10, Phase::kPlant, &rec);
  ASSERT_TRUE(queue.step());
  EXPECT_DEATH(queue.schedule(9, Phase::kMetrics, &rec), "check failed: time >= now_");
  queue.run_until(50);
  EXPECT_DEATH(queue.schedule(49, Phase::kPlant, &rec), "check failed: time >= now_");
  EXPECT_DEATH(queue.schedule(50, Phase::kPlant, nullptr), "check failed: handler != nullptr");
  queue.schedule(50, Phase::kPlant, &rec);  // exactly now() is fine
  EXPECT_EQ(queue.size(), 1u);
}

}  // namespace
}  // namespace ncosim::kernel
