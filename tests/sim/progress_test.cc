// tests/sim/progress_test.cc — the campaign's progress line (sim/run/progress.h), on an injected
// clock (no sleeps): one format; in a log a line 2 s after the start and then on the 5 s grid
// over the whole campaign (never restarted by a new case); on a terminal the line redrawn in
// place; the runs stored before counted as done but not in the rate.
#include "sim/run/progress.h"

#include <gtest/gtest.h>

#include <string>
#include <vector>

namespace {

using ncosim::sim::CampaignProgress;
using ncosim::sim::format_duration;

// A clock the test sets, and the texts written.
struct Fake {
  double now = 100.0;
  std::vector<std::string> written;
  CampaignProgress make(CampaignProgress::Mode mode) {
    return CampaignProgress(
        mode, [this] { return now; }, [this](const std::string& s) { written.push_back(s); });
  }
};

TEST(Progress, FormatsTheWholeCampaignWithCaseRateAndEta) {
  Fake f;
  CampaignProgress p(CampaignProgress::Mode::log, [&] { return f.now; }, {});
  p.set_total(60, 0, false);
  p.set_case(1, 3);
  EXPECT_EQ(p.line(100.0), "ncosim: case 2/3, 0/60 runs, 0.00 runs/s, elapsed 0s, ETA ?");
  p.add_done(27);
  // 27 runs in 5 s: 5.4 runs/s; 33 left: 6.1 s.
  EXPECT_EQ(p.line(105.0), "ncosim: case 2/3, 27/60 runs, 5.40 runs/s, elapsed 5s, ETA 6s");
  p.add_done(33);
  EXPECT_EQ(p.line(200.0), "ncosim: case 2/3, 60/60 runs, 0.60 runs/s, elapsed 1m40s, ETA 0s");
}

TEST(Progress, RunsStoredBeforeCountAsDoneButNotInTheRate) {
  Fake f;
  CampaignProgress p(CampaignProgress::Mode::log, [&] { return f.now; }, {});
  p.set_total(60, 24, false);
  EXPECT_EQ(p.line(100.0), "ncosim: 24/60 runs (24 stored before), 0.00 runs/s, elapsed 0s, ETA ?");
  p.add_done(12);  // 12 simulated in 4 s: 3 runs/s, 24 left: 8 s
  EXPECT_EQ(p.line(104.0),
            "ncosim: 36/60 runs (24 stored before), 3.00 runs/s, elapsed 4s, ETA 8s");
}

TEST(Progress, TargetCiSaysTheTotalIsAnUpperBound) {
  Fake f;
  CampaignProgress p(CampaignProgress::Mode::log, [&] { return f.now; }, {});
  p.set_total(400, 0, true);
  p.set_case(0, 2, "runs 20..39");
  p.add_done(150);
  EXPECT_EQ(p.line(110.0),
            "ncosim: case 1/2 (runs 20..39), 150 of at most 400 runs (--target-ci), 15.0 runs/s, "
            "elapsed 10s, "
            "ETA at most 17s");
  p.set_case(0, 1, "runs 0..19");
  p.add_done(1850);  // 2000 in 10 s: no exponent
  EXPECT_EQ(p.line(110.0),
            "ncosim: runs 0..19, 2000 of at most 400 runs (--target-ci), 200 runs/s, elapsed 10s, "
            "ETA at most 0s");
}

// A log: the first line 2 s after the start, then at 5, 10, 15 s ... of the campaign, whatever
// the cases do; a late wake-up does not shift the grid.
TEST(Progress, LogLinesFollowTheCampaignClockNotTheCases) {
  Fake f;
  CampaignProgress p = f.make(CampaignProgress::Mode::log);
  p.set_total(100, 0, false);
  std::vector<double> at;
  for (int tick = 0; tick <= 100; ++tick) {  // 20 s polled every 0.2 s; a new case every 3 s
    f.now = 100.0 + tick / 5.0;
    if (tick % 15 == 0) p.set_case(static_cast<std::size_t>(tick / 15), 7);
    p.add_done(1);
    if (!p.poll(f.now).empty()) at.push_back(f.now - 100.0);
  }
  ASSERT_EQ(at.size(), 5u);
  const std::vector<double> expected{2.0, 5.0, 10.0, 15.0, 20.0};
  for (std::size_t i = 0; i < at.size(); ++i) EXPECT_NEAR(at[i], expected[i], 1e-9) << i;
  // A wake-up 1.3 s late writes one line and the next is on the grid again.
  f.now = 126.3;
  EXPECT_FALSE(p.poll(f.now).empty());
  EXPECT_TRUE(p.poll(129.9).empty());
  const std::string line = p.poll(130.0);
  EXPECT_EQ(line.back(), '\n');
  EXPECT_EQ(line.rfind("ncosim: case 7/7, ", 0), 0u) << line;
}

TEST(Progress, AShortCampaignStillGetsALogLineWithinFiveSeconds) {
  Fake f;
  CampaignProgress p = f.make(CampaignProgress::Mode::log);
  p.set_total(60, 0, false);
  EXPECT_TRUE(p.poll(101.9).empty());
  EXPECT_FALSE(p.poll(102.1).empty());
}

TEST(Progress, ATerminalLineIsRedrawnInPlaceAndEndsWithANewline) {
  Fake f;
  {
    CampaignProgress p = f.make(CampaignProgress::Mode::terminal);
    p.set_total(1000, 0, false);
    p.add_done(999);
    f.now = 101.0;
    const std::string a = p.poll(f.now);
    EXPECT_EQ(a, "\rncosim: 999/1000 runs, 999 runs/s, elapsed 1s, ETA 0s");
    // A shorter line blanks the rest of the longer one.
    CampaignProgress q = f.make(CampaignProgress::Mode::terminal);
    q.set_total(1000, 0, false);
    const std::string longer = q.poll(200.0), shorter = q.poll(105.0);
    EXPECT_EQ(shorter.size(), longer.size()) << longer << "|" << shorter;
    EXPECT_EQ(shorter.back(), ' ');
    p.start();
    p.finish();  // the last state stays on the terminal, ended by a newline
    ASSERT_FALSE(f.written.empty());
    EXPECT_EQ(f.written.back(), a + "\n");
  }
  CampaignProgress off = f.make(CampaignProgress::Mode::off);
  EXPECT_TRUE(off.poll(1e9).empty());
  EXPECT_FALSE(off.on());
}

TEST(Progress, DurationsReadAsAUserWritesThem) {
  EXPECT_EQ(format_duration(4.4), "4s");
  EXPECT_EQ(format_duration(65.0), "1m05s");
  EXPECT_EQ(format_duration(7380.0), "2h03m");
  EXPECT_EQ(format_duration(-1.0), "?");
}

}  // namespace
