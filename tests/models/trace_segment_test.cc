// tests/models/trace_segment_test.cc — the `trace` link's `segment`: run r replays rows
// s S .. s S + S - 1 with s = r mod floor(rows / S) (rows past the last whole segment never
// replayed), a clone starts unbound, the packet bound is S, and the design law stays the whole
// trace's.
#include <gtest/gtest.h>

#include <optional>
#include <vector>

#include "kernel/rng.h"
#include "models/link.h"

namespace {

using ncosim::models::kLost;
using ncosim::models::TraceLink;

TEST(TraceLinkSegment, RunRReplaysItsOwnSegmentCyclically) {
  // 7 rows, segment 2: segments {0, 1}, {2, 3}, {4, 5}; row 6 is never replayed.
  TraceLink link({0, std::nullopt, 1, 2, std::nullopt, 3, 4}, 2);
  ncosim::kernel::Rng rng(5);
  const std::vector<std::vector<std::int64_t>> by_run = {
      {0, kLost}, {1, 2}, {kLost, 3}, {0, kLost}, {1, 2}};
  for (std::uint64_t r = 0; r < by_run.size(); ++r) {
    auto run = link.clone();
    ncosim::models::bind_run(*run, nullptr, 9, r);
    run->reset(rng);
    for (std::size_t k = 0; k < 2; ++k)
      EXPECT_EQ(run->transmit(rng), by_run[r][k]) << "run " << r << ", packet " << k;
    run->reset(rng);  // reset rewinds to the run's segment, not to row 0
    EXPECT_EQ(run->transmit(rng), by_run[r][0]) << "run " << r;
  }
  ASSERT_TRUE(link.packet_bound().has_value());
  EXPECT_EQ(link.packet_bound()->packets, 2);
  EXPECT_EQ(link.packet_bound()->key, "segment");
  // The design law is the whole file's: 2 of 7 lost.
  EXPECT_DOUBLE_EQ(link.loss_probability(), 2.0 / 7.0);
  // Without a segment every run replays from row 0 and the bound is the file.
  TraceLink whole({0, std::nullopt, 1});
  auto run = whole.clone();
  ncosim::models::bind_run(*run, nullptr, 9, 4);
  run->reset(rng);
  EXPECT_EQ(run->transmit(rng), 0);
  EXPECT_EQ(whole.packet_bound()->packets, 3);
  EXPECT_EQ(whole.packet_bound()->key, "file");
}

}  // namespace
