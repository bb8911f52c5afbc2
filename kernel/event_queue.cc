// kernel/event_queue.cc — radix heap on time over a block pool, binary heap for the current
// instant.
#include "kernel/event_queue.h"

#include <algorithm>
#include <bit>

#include "kernel/check.h"

namespace ncosim::kernel {

namespace {
constexpr int kPhaseShift = 56;
constexpr std::uint64_t kSeqMask = (std::uint64_t{1} << kPhaseShift) - 1;

// std heaps are max-heaps; ordering by "later key" puts the earliest key on top.
struct LaterKey {
  bool operator()(const EventQueue::Event& a, const EventQueue::Event& b) const {
    return a.key > b.key;
  }
};
}  // namespace

std::uint32_t EventQueue::take_block() {
  if (free_ == kNoBlock) {
    NCOSIM_CHECK(next_.size() < kNoBlock);
    free_ = static_cast<std::uint32_t>(next_.size());
    next_.push_back(kNoBlock);
    slots_.resize(slots_.size() + kBlockEvents);
  }
  const std::uint32_t block = free_;
  free_ = next_[block];
  return block;
}

inline void EventQueue::push(Bucket& bucket, const Event& e) {
  if (bucket.fill == kBlockEvents) {
    const std::uint32_t block = take_block();
    next_[block] = bucket.head;
    bucket.head = block;
    bucket.fill = 0;
  }
  slot(bucket.head, bucket.fill++) = e;
}

// Returns every block of bucket b but the head to the free list and clears b's bit.
void EventQueue::empty_bucket(int b) {
  Bucket& bucket = buckets_[static_cast<std::size_t>(b)];
  if (bucket.head != kNoBlock) {
    std::uint32_t block = next_[bucket.head];
    while (block != kNoBlock) {
      const std::uint32_t next = next_[block];
      next_[block] = free_;
      free_ = block;
      block = next;
    }
    next_[bucket.head] = kNoBlock;
    bucket.fill = 0;
  }
  const auto d = static_cast<std::size_t>(b / kRadix);
  occupied_[d] &= ~(std::uint32_t{1} << (b % kRadix));
  if (occupied_[d] == 0) digits_ &= ~(std::uint32_t{1} << d);
}

void EventQueue::reserve(std::size_t n) {
  const std::size_t blocks = n / kBlockEvents + 1;
  next_.reserve(blocks);
  slots_.reserve(blocks * kBlockEvents);
}

// An event at base_ joins the current instant, any other the bucket of the highest digit in
// which its time differs from base_ (digit 12 at most, as times are below 2^63).
inline void EventQueue::place(const Event& e) {
  const auto diff = static_cast<std::uint64_t>(e.time ^ base_);
  if (diff == 0) {
    current_.push_back(e);
    std::push_heap(current_.begin(), current_.end(), LaterKey{});
    return;
  }
  const int d = (std::bit_width(diff) - 1) / kDigitBits;
  const int v =
      static_cast<int>(static_cast<std::uint64_t>(e.time) >> (d * kDigitBits)) & (kRadix - 1);
  push(buckets_[static_cast<std::size_t>(d * kRadix + v)], e);
  occupied_[static_cast<std::size_t>(d)] |= std::uint32_t{1} << v;
  digits_ |= std::uint32_t{1} << d;
}

void EventQueue::schedule(SimTime time, Phase phase, EventHandler* handler, std::uint64_t arg) {
  NCOSIM_CHECK(time >= now_);
  NCOSIM_CHECK(handler != nullptr);
  const std::uint64_t key =
      (static_cast<std::uint64_t>(phase) << kPhaseShift) | (seq_++ & kSeqMask);
  place(Event{time, key, handler, arg});
  ++size_;
}

// Buckets are ordered by (digit, value). Requires a non-empty bucket.
int EventQueue::lowest_bucket() const {
  const int d = std::countr_zero(digits_);
  return d * kRadix + std::countr_zero(occupied_[static_cast<std::size_t>(d)]);
}

SimTime EventQueue::bucket_min(int b) const {
  const Bucket& bucket = buckets_[static_cast<std::size_t>(b)];
  SimTime m = slot(bucket.head, 0).time;
  std::uint32_t n = bucket.fill;
  for (std::uint32_t block = bucket.head; block != kNoBlock; block = next_[block]) {
    for (std::uint32_t i = 0; i < n; ++i) m = std::min(m, slot(block, i).time);
    n = kBlockEvents;
  }
  return m;
}

// Re-bases on m, the earliest time of bucket b, the lowest one (requires current_ empty).
// b's events agree with m above their digit, so each moves to a lower bucket or to current_;
// every other bucket keeps its (digit, value) relative to m. Blocks are freed as they are
// emptied, so a large bucket does not need twice its size in the pool.
void EventQueue::refill(int b, SimTime m) {
  base_ = m;
  const std::uint32_t head = buckets_[static_cast<std::size_t>(b)].head;
  std::uint32_t n = buckets_[static_cast<std::size_t>(b)].fill;
  for (std::uint32_t block = head; block != kNoBlock;) {
    for (std::uint32_t i = 0; i < n; ++i) {
      const Event e = slot(block, i);  // a copy: place() may grow slots_
      place(e);
    }
    const std::uint32_t next = next_[block];
    if (block != head) {
      next_[block] = free_;
      free_ = block;
    }
    block = next;
    n = kBlockEvents;
  }
  next_[head] = kNoBlock;
  empty_bucket(b);
}

inline void EventQueue::dispatch(const Event& e) {
  --size_;
  now_ = e.time;
  e.handler->handle(e.time, e.arg);
}

bool EventQueue::step() {
  if (size_ == 0) return false;
  if (current_.empty()) {
    const int b = lowest_bucket();
    const Bucket& bucket = buckets_[static_cast<std::size_t>(b)];
    if (bucket.fill == 1 && next_[bucket.head] == kNoBlock) {
      // A lone earliest event (the common case when instants rarely coincide): dispatch it
      // straight from its bucket, as refill() and a pop from current_ would.
      const Event e = slot(bucket.head, 0);
      empty_bucket(b);
      base_ = e.time;
      dispatch(e);
      return true;
    }
    refill(b, bucket_min(b));
  }
  std::pop_heap(current_.begin(), current_.end(), LaterKey{});
  const Event e = current_.back();
  current_.pop_back();
  dispatch(e);
  return true;
}

void EventQueue::run_until(SimTime until) {
  while (size_ != 0) {
    if (current_.empty()) {
      const int b = lowest_bucket();
      const SimTime m = bucket_min(b);
      if (m > until) break;
      refill(b, m);
    } else if (base_ > until) {
      break;
    }
    step();
  }
  if (now_ < until) now_ = until;
}

const EventQueue::Event& EventQueue::top() const {
  if (!current_.empty()) return current_.front();
  const Bucket& bucket = buckets_[static_cast<std::size_t>(lowest_bucket())];
  const Event* best = &slot(bucket.head, 0);
  std::uint32_t n = bucket.fill;
  for (std::uint32_t block = bucket.head; block != kNoBlock; block = next_[block]) {
    for (std::uint32_t i = 0; i < n; ++i) {
      const Event& e = slot(block, i);
      if (e.time < best->time || (e.time == best->time && e.key < best->key)) best = &e;
    }
    n = kBlockEvents;
  }
  return *best;
}

void EventQueue::clear() {
  for (int b = 0; b < kDigits * kRadix; ++b) empty_bucket(b);
  current_.clear();
  size_ = 0;
  base_ = 0;
  now_ = 0;
  seq_ = 0;
}

}  // namespace ncosim::kernel
