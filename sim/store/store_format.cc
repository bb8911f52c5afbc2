// sim/store/store_format.cc — see sim/store/store_format.h.
#include "sim/store/store_format.h"

#include <fmt/format.h>

#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <vector>

namespace ncosim::sim {

// Whoever adds a field to EstimatorRunMetrics must add it to serialize_run/deserialize_run
// (and bump kRunBlobFormat), or stored campaigns would silently lose it on export, resume and
// merge.
static_assert(sizeof(EstimatorRunMetrics) == 328 || sizeof(void*) != 8,
              "EstimatorRunMetrics changed: update serialize_run/deserialize_run in "
              "sim/store/store_format.cc");

namespace {

// Version of the run blob (2: NEES and NIS sums; 3: the error blocks of the error-growth note).
constexpr std::uint32_t kRunBlobFormat = 3;
// Version of the link counters blob (2: a network node's stack counters; 3: the run's delay blocks
// of the overload test; format 1 and 2 blobs, without them, are still read).
constexpr std::uint32_t kLinksFormat = 3;

class Writer {
 public:
  void u8(std::uint8_t v) { out_.push_back(static_cast<char>(v)); }
  void i64(std::int64_t v) { raw(static_cast<std::uint64_t>(v)); }
  void f64(double v) { raw(std::bit_cast<std::uint64_t>(v)); }
  void size(std::size_t v) { raw(static_cast<std::uint64_t>(v)); }
  void str(const std::string& s) {
    size(s.size());
    out_ += s;
  }
  void f64s(const std::vector<double>& v) {
    size(v.size());
    for (double x : v) f64(x);
  }
  void i64s(const std::vector<std::int64_t>& v) {
    size(v.size());
    for (auto x : v) i64(x);
  }
  std::string take() { return std::move(out_); }

 private:
  void raw(std::uint64_t v) {  // little-endian, whatever the host
    for (int i = 0; i < 8; ++i) out_.push_back(static_cast<char>((v >> (8 * i)) & 0xFF));
  }
  std::string out_;
};

class Reader {
 public:
  explicit Reader(const std::string& in) : in_(in) {}
  std::uint8_t u8() {
    need(1);
    return static_cast<std::uint8_t>(in_[pos_++]);
  }
  std::int64_t i64() { return static_cast<std::int64_t>(raw()); }
  double f64() { return std::bit_cast<double>(raw()); }
  std::size_t size() {
    const std::uint64_t v = raw();
    if (v > in_.size() - pos_)
      throw StoreError("run store: corrupt run record (length beyond the record)");
    return static_cast<std::size_t>(v);
  }
  std::string str() {
    const std::size_t n = size();
    need(n);
    std::string s = in_.substr(pos_, n);
    pos_ += n;
    return s;
  }
  std::vector<double> f64s() {
    std::vector<double> v(size());
    for (auto& x : v) x = f64();
    return v;
  }
  std::vector<std::int64_t> i64s() {
    std::vector<std::int64_t> v(size());
    for (auto& x : v) x = i64();
    return v;
  }
  bool at_end() const { return pos_ == in_.size(); }

 private:
  void need(std::size_t n) const {
    if (in_.size() - pos_ < n) throw StoreError("run store: corrupt run record (truncated)");
  }
  std::uint64_t raw() {
    need(8);
    std::uint64_t v = 0;
    for (int i = 0; i < 8; ++i)
      v |= static_cast<std::uint64_t>(static_cast<unsigned char>(in_[pos_ + i])) << (8 * i);
    pos_ += 8;
    return v;
  }
  const std::string& in_;
  std::size_t pos_ = 0;
};

}  // namespace

std::string serialize_run(const RunMetrics& run) {
  Writer w;
  w.i64(kRunBlobFormat);
  w.size(run.size());
  for (const EstimatorRunMetrics& m : run) {
    w.f64(m.sse);
    w.f64(m.sse_ext);
    w.f64s(m.sse_state);
    w.i64(m.count);
    w.i64(m.samples_used);
    w.i64(m.samples_taken);
    w.i64s(m.sensor_taken);
    w.i64s(m.sensor_sent);
    w.size(m.sensor_virtual_sse.size());
    for (const auto& v : m.sensor_virtual_sse) w.f64s(v);
    w.u8(m.diverged ? 1 : 0);
    w.str(m.status);
    w.i64(m.mode_count);
    w.i64(m.mode_errors);
    w.i64s(m.confusion);
    w.u8(m.counters ? 1 : 0);
    if (m.counters) {
      w.f64(m.counters->flops);
      w.f64(m.counters->flops_worst);
      w.i64(m.counters->periods);
      w.i64(m.counters->late);
      w.i64(m.counters->duplicates);
    }
    w.f64(m.nees);
    w.i64(m.nees_count);
    w.f64(m.nis);
    w.i64(m.nis_dof);
    w.i64(m.nis_count);
    w.f64s(m.sse_blocks);
  }
  return w.take();
}

RunMetrics deserialize_run(const std::string& blob) {
  Reader r(blob);
  const std::int64_t format = r.i64();
  if (format < 1 ||
      format > kRunBlobFormat) {  // format 1 has no NEES/NIS sums (counts 0: no column)
    throw StoreError(
        fmt::format("run store: run record format {} (this ncosim reads formats 1 to {})", format,
                    kRunBlobFormat));
  }
  RunMetrics run(r.size());
  for (EstimatorRunMetrics& m : run) {
    m.sse = r.f64();
    m.sse_ext = r.f64();
    m.sse_state = r.f64s();
    m.count = r.i64();
    m.samples_used = r.i64();
    m.samples_taken = r.i64();
    m.sensor_taken = r.i64s();
    m.sensor_sent = r.i64s();
    m.sensor_virtual_sse.resize(r.size());
    for (auto& v : m.sensor_virtual_sse) v = r.f64s();
    m.diverged = r.u8() != 0;
    m.status = r.str();
    m.mode_count = r.i64();
    m.mode_errors = r.i64();
    m.confusion = r.i64s();
    if (r.u8() != 0) {
      est::Estimator::RunCounters c;
      c.flops = r.f64();
      c.flops_worst = r.f64();
      c.periods = r.i64();
      c.late = r.i64();
      c.duplicates = r.i64();
      m.counters = c;
    }
    if (format >= 2) {
      m.nees = r.f64();
      m.nees_count = r.i64();
      m.nis = r.f64();
      m.nis_dof = r.i64();
      m.nis_count = r.i64();
    }
    if (format >= 3) m.sse_blocks = r.f64s();
  }
  if (!r.at_end()) throw StoreError("run store: corrupt run record (trailing bytes)");
  return run;
}

std::string serialize_links(const RunLinks& links) {
  Writer w;
  w.i64(kLinksFormat);
  w.size(links.size());
  for (const models::LinkCounters& c : links) {
    w.i64(c.sent);
    w.i64(c.delivered);
    w.i64s(c.copies);
    w.i64s(c.bursts);
    w.i64s(c.states);
    w.i64(c.open_burst);
    w.u8(c.stack ? 1 : 0);
    if (c.stack) {
      w.i64(c.stack->attempts);
      w.i64(c.stack->retries);
      w.i64s(c.stack->drops);
      w.i64(c.stack->busy_ns);
      w.i64(c.stack->simulated_ns);
    }
    w.i64(c.blocks.size);  // the full blocks (the one being filled is not a block)
    w.i64s(c.blocks.delivered);
    w.i64s(c.blocks.delay);
  }
  return w.take();
}

RunLinks deserialize_links(const std::string& blob) {
  Reader r(blob);
  const std::int64_t format = r.i64();
  if (format < 1 || format > kLinksFormat) {
    throw StoreError(
        fmt::format("run store: link counters format {} (this ncosim reads formats 1 to {})",
                    format, kLinksFormat));
  }
  RunLinks links(r.size());
  for (models::LinkCounters& c : links) {
    c.sent = r.i64();
    c.delivered = r.i64();
    c.copies = r.i64s();
    c.bursts = r.i64s();
    c.states = r.i64s();
    c.open_burst = r.i64();
    if (format >= 2 && r.u8() != 0) {
      models::StackCounters& k = c.stack.emplace();
      k.attempts = r.i64();
      k.retries = r.i64();
      k.drops = r.i64s();
      k.busy_ns = r.i64();
      k.simulated_ns = r.i64();
    }
    if (format >= 3) {
      c.blocks.size = r.i64();
      c.blocks.delivered = r.i64s();
      c.blocks.delay = r.i64s();
      if (c.blocks.size < 1 || c.blocks.delivered.size() != c.blocks.delay.size())
        throw StoreError("run store: corrupt link counters (delay blocks)");
    }
  }
  if (!r.at_end()) throw StoreError("run store: corrupt link counters (trailing bytes)");
  return links;
}

}  // namespace ncosim::sim
