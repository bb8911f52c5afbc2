// tests/cli/reliability_test.cc — hostile input, resource limits and kills, as a user meets
// them through the ncosim executable: each test is a regression test of one finding of the
// reliability probe (exit 2 with FILE:LINE for bad input, exit 1 with a message for a failure that
// is not bad input, never an abort, a silent status or a mixed result set).
#include <fcntl.h>
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <poll.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <regex>
#include <string>
#include <vector>

#include "cli/small_trace_scenario.h"
#include "test_util.h"

namespace {

namespace fs = std::filesystem;
using Outcome = ncosim::testing::CommandOutcome;

const fs::path kSource = NCOSIM_SOURCE_DIR;

Outcome ncosim(const std::vector<std::string>& args, const std::string& prefix = "") {
  return ncosim::testing::run_shell(prefix + ncosim::testing::ncosim_command(args));
}

class Reliability : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           fmt::format("ncosim_reliability_{}_{}", ::getpid(),
                       ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string write(const std::string& name, const std::string& text) {
    const fs::path p = dir_ / name;
    std::ofstream(p, std::ios::binary) << text;
    return p.string();
  }
  fs::path dir_;
};

const std::string& kSmall = ncosim::testing::kSmallTraceScenario;

std::string trace_csv(int packets) { return ncosim::testing::small_trace_csv(packets); }

// Finding 1: a transfer function with a long dead time made `check` exit 205 with nothing on
// stderr after 3.7 GB (CSDP's malloc failure exits the process). Now the design is estimated
// first and refused with exit 2 naming the key, the estimate and the limit, within seconds.
TEST_F(Reliability, DeadTimeDesignIsRefusedBeforeItStarts) {
  const std::string text = R"([run]
period = 0.005
[plant]
kind = "transfer_function"
num = [1.0]
den = [1.0, 1.0]
dead_time = 1.01
[[sensor]]
C = "output"
R = 0.25
[[estimator]]
kind = "sod_jump"
w_rms = 0.1
)";
  const std::string file = write("dead_time.toml", text);
  const auto t0 = std::chrono::steady_clock::now();
  const Outcome o = ncosim({"check", file});
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_EQ(o.code, 2) << o.output;
  EXPECT_NE(o.output.find(file + ":12: key 'estimator[0].kind'"), std::string::npos) << o.output;
  EXPECT_NE(o.output.find("plant.dead_time"), std::string::npos) << o.output;
  EXPECT_NE(o.output.find("limit"), std::string::npos) << o.output;
  EXPECT_LT(s, 20.0);
}

// Issue 29, finding 11: with raised limits the same design passed the estimate and CSDP, out of
// address space, ended the process with exit 205 and nothing on stderr (49 s, 3.7 GB under
// `ulimit -v 6000000`). An estimate above the address-space limit is refused before the solve.
TEST_F(Reliability, DeadTimeDesignBeyondTheAddressSpaceIsRefusedNotExit205) {
  const std::string file = write("dead_time.toml", R"([run]
period = 0.005
[plant]
kind = "transfer_function"
num = [1.0]
den = [1.0, 1.0]
dead_time = 1.01
[[sensor]]
C = "output"
R = 0.25
[[estimator]]
kind = "sod_jump"
w_rms = 0.1
)");
  const auto t0 = std::chrono::steady_clock::now();
  const Outcome o = ncosim({"check", file, "--max-memory", "300000", "--max-work", "1e9"},
                           "ulimit -v 2000000; timeout 120 ");
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_EQ(o.code, 2) << o.output;
  EXPECT_NE(o.output.find(file + ":12: key 'estimator[0].kind'"), std::string::npos) << o.output;
  EXPECT_NE(o.output.find("above the process's address-space limit of 2.0 GB (ulimit -v"),
            std::string::npos)
      << o.output;
  EXPECT_LT(s, 20.0);
}

// Issue 29, finding 11: the note of a design estimated above 256 MB or 10 GFLOP never appeared
// for send-on-delta (LMI) designs; it is printed before the solve.
TEST_F(Reliability, SendOnDeltaDesignsGetTheLargeDesignNote) {
  const Outcome o = ncosim({"check", (kSource / "scenarios" / "sod_example52.toml").string(),
                            "--set", "plant.dead_time=0.1"});
  EXPECT_EQ(o.code, 0) << o.output;
  EXPECT_NE(o.output.find(
                "ncosim: note: estimator[0].kind: the sod_jump design solves an LMI problem of"),
            std::string::npos)
      << o.output;
  EXPECT_NE(o.output.find("its size is driven by plant.dead_time"), std::string::npos) << o.output;
}

// Issue 29, finding 14: --max-work 0.01 printed "estimated 0 GFLOP, above the work limit of 0
// GFLOP".
TEST_F(Reliability, SmallWorkLimitsArePrintedWithTheirDigits) {
  write("trace.csv", trace_csv(400));
  // (kalman_extended's estimate is its design since issue 26: 4 products of the extended state.)
  const Outcome o = ncosim({"check", write("small.toml", kSmall), "--max-work", "0.0000001"});
  EXPECT_EQ(o.code, 2) << o.output;
  EXPECT_NE(o.output.find("needs an estimated 5e-07 GFLOP, above the work limit of 1e-07 GFLOP"),
            std::string::npos)
      << o.output;
}

// Finding 6: valid but large inputs are refused with the key that drives the size; the
// option raises the limit.
// Finding 6: a jump S4 design with max_delay 7 passed `check` with an estimate of 37 MB and then
// took 30 s and 573 MB (history 2; 56 s and 1.1 GB at history 4). The estimate now counts the
// per-term matrices and the delay-extended operators (810 MB here, 573 MB measured), so a 400 MB
// limit refuses it at once, naming the keys.
TEST_F(Reliability, JumpDesignMemoryEstimateCountsThePatternTerms) {
  const std::string file = (kSource / "scenarios" / "dolz2014_table2.toml").string();
  const auto t0 = std::chrono::steady_clock::now();
  const Outcome o = ncosim({"check", file, "--set", "estimator[4].max_delay=7", "--set",
                            "estimator[4].history=2", "--max-memory", "400"});
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_EQ(o.code, 2) << o.output;
  EXPECT_NE(o.output.find("key 'estimator[4].kind': the jump design needs an estimated"),
            std::string::npos)
      << o.output;
  EXPECT_NE(o.output.find("above the memory limit"), std::string::npos) << o.output;
  EXPECT_NE(o.output.find("2 x 2^16 terms"), std::string::npos) << o.output;
  EXPECT_LT(seconds, 10.0);
}

// A jump size the reader refuses (more than 2^20 availability patterns) is reported by the reader,
// naming what is supported; the cost estimate (48.7 GB here) used to come first and gave a memory
// limit message for a design that cannot be made at any limit.
TEST_F(Reliability, AJumpSizeTheReaderRefusesGetsTheReadersMessage) {
  const std::string file = (kSource / "scenarios" / "dolz2014_fig1a.toml").string();
  const Outcome o = ncosim({"check", file, "--set", "estimator[0].max_delay=10"});
  EXPECT_EQ(o.code, 2) << o.output;
  EXPECT_NE(o.output.find("key 'estimator[0].max_delay': the design enumerates 2^22 availability "
                          "patterns (2 sensors x 11 delays); at most 2^20 are supported"),
            std::string::npos)
      << o.output;
  EXPECT_EQ(o.output.find("memory limit"), std::string::npos) << o.output;
}

TEST_F(Reliability, LargeDesignsNameTheKeyTheEstimateAndTheLimit) {
  const int n = 300;
  std::string a = "[", bw = "[", c = "[[";
  for (int i = 0; i < n; ++i) {
    a += i ? ", [" : "[";
    for (int j = 0; j < n; ++j) a += fmt::format("{}{}", j ? ", " : "", i == j ? 0.5 : 0.0);
    a += "]";
    bw += i ? ", [1.0]" : "[1.0]";
    c += i ? ", 0.0" : "1.0";
  }
  a += "]";
  bw += "]";
  c += "]]";
  const std::string file = write("big.toml", fmt::format(R"([plant]
kind = "lti"
A = {}
Bw = {}
W = 1.0
[[sensor]]
C = {}
R = 1.0
[[estimator]]
kind = "kalman_extended"
max_delay = 62
)",
                                                         a, bw, c));
  const Outcome o = ncosim({"check", file});
  EXPECT_EQ(o.code, 2) << o.output.substr(0, 2000);
  EXPECT_NE(
      o.output.find(file +
                    ":10: key 'estimator[0].kind': the kalman_extended design needs an estimated"),
      std::string::npos)
      << o.output.substr(0, 2000);
  EXPECT_NE(o.output.find("above the memory limit of 4.0 GB (--max-memory); its size is driven by "
                          "estimator[0].max_delay (with plant.A (300 plant states))"),
            std::string::npos)
      << o.output.substr(0, 2000);
  // A small work limit refuses a small design; the default passes it.
  write("trace.csv", trace_csv(400));
  const std::string small = write("small.toml", kSmall);
  const Outcome refused = ncosim({"check", small, "--max-work", "0.00000001"});
  EXPECT_EQ(refused.code, 2) << refused.output;
  EXPECT_NE(refused.output.find("work limit"), std::string::npos) << refused.output;
  const Outcome passes = ncosim({"check", small});
  EXPECT_EQ(passes.code, 0) << passes.output;
}

std::string many_sensors(int sensors, const std::string& plant, const std::string& C,
                         const std::string& estimators) {
  std::string text = "[run]\nperiods = 100\nruns = 2\n[plant]\n" + plant +
                     "\n[[link]]\nname = \"net\"\n"
                     "kind = \"bernoulli\"\nloss = 0.2\n";
  for (int i = 0; i < sensors; ++i)
    text += fmt::format("[[sensor]]\nC = {}\nR = 1.0\nlink = \"net\"\n", C);
  return text + estimators;
}

// Issue 29, finding 12: 1001 [[sensor]] tables on an open-loop-unstable plant kept `check` silent
// for minutes (15.7 s at 400 sensors, growing as the cube of the sensors): the buffer estimators'
// critical probability (design.json) ran its SDP and its bisection on all 1001 stacked rows. The
// rows are now compressed to n with the same information: 0.03 s.
TEST_F(Reliability, ThousandSensorsOnAnUnstablePlantAreCheckedInSeconds) {
  const std::string file = write(
      "many.toml", many_sensors(1001, "A = [[1.2, 0.1], [0.0, 0.8]]\nW = [[1.0, 0.0], [0.0, 1.0]]",
                                "[[1.0, 0.0]]",
                                "[[estimator]]\nkind = \"kalman_buffer\"\nbuffer = 2\n"
                                "[[estimator]]\nkind = \"static_buffer\"\nbuffer = 2\n"));
  const auto t0 = std::chrono::steady_clock::now();
  const Outcome o = ncosim({"check", file}, "timeout 60 ");
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_EQ(o.code, 0) << o.output.substr(0, 2000);
  EXPECT_NE(o.output.find("ok (1 case(s), 2 estimator(s))"), std::string::npos)
      << o.output.substr(0, 2000);
  EXPECT_LT(s, 10.0);
}

// Issue 29, finding 12: static_buffer's fourth-moment radius multiplies an n^4 x n^4 matrix once
// per sensor (5 states and 1001 sensors: about 7 minutes) and was not in the estimate. It is now
// (522 GFLOP since issue 26: the eigenvalue solve measured at 64 products, and the critical
// probability's bisection on this unstable plant):
// a work limit refuses it at once naming the plant and the sensors, and the default limits print
// the large-design note before the design starts.
TEST_F(Reliability, StaticBufferFourthMomentIsCountedPerSensor) {
  const std::string file =
      write("many.toml",
            many_sensors(
                1001,
                "A = [[1.1, 0.1, 0, 0, 0], [0, 0.9, 0.1, 0, 0], [0, 0, 0.9, 0.1, 0], "
                "[0, 0, 0, 0.9, 0.1], [0, 0, 0, 0, 0.9]]\nBw = [[1], [1], [1], [1], [1]]\nW = 1.0",
                "[[1.0, 0, 0, 0, 0]]", "[[estimator]]\nkind = \"static_buffer\"\nbuffer = 2\n"));
  const auto t0 = std::chrono::steady_clock::now();
  const Outcome o = ncosim({"check", file, "--max-work", "100"}, "timeout 60 ");
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_EQ(o.code, 2) << o.output.substr(0, 2000);
  EXPECT_NE(
      o.output.find(
          "key 'estimator[0].kind': the static_buffer design needs an estimated 522 GFLOP, above "
          "the "
          "work limit of 100 GFLOP (--max-work); its size is driven by plant.A (5 plant states) "
          "and "
          "the 1001 sensor(s) (the fourth-moment operator is 625 x 625, one product per sensor)"),
      std::string::npos)
      << o.output.substr(0, 2000);
  EXPECT_LT(s, 10.0);
}

// Issue 26: a 60-state plant with static_buffer and kalman_buffer at buffer = 400 ran `check` for
// minutes without a word, even with --max-work 1 (the estimate read max_delay, not buffer, and
// missed static_buffer's 3600 x 3600 second-moment operators). Each kind now estimates its own
// design: refused at the default limits within seconds, naming the operator.
TEST_F(Reliability, SixtyStateBufferDesignsAreRefusedWithinSeconds) {
  const std::string file =
      (kSource / "tests" / "cli" / "data" / "sixty_states_buffer.toml").string();
  const std::vector<std::vector<std::string>> limits{{}, {"--max-work", "1"}};
  for (const auto& extra : limits) {
    std::vector<std::string> args{"check", file};
    args.insert(args.end(), extra.begin(), extra.end());
    const auto t0 = std::chrono::steady_clock::now();
    const Outcome o = ncosim(args, "timeout 60 ");
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    EXPECT_EQ(o.code, 2) << o.output;
    EXPECT_NE(o.output.find("key 'estimator[0].kind': the static_buffer design needs an estimated"),
              std::string::npos)
        << o.output;
    EXPECT_NE(o.output.find("(--max-work); its size is driven by plant.A (60 plant states) (the "
                            "second-moment operator is 3600 x 3600)"),
              std::string::npos)
        << o.output;
    EXPECT_LT(s, 10.0);
  }
}

// Finding 2: threads that cannot be created gave `terminate called without an active
// exception` (SIGABRT); now exit 1 with a message.
TEST_F(Reliability, ThreadCreationFailureIsExitOneWithAMessage) {
  write("trace.csv", trace_csv(400));
  const std::string file = write("small.toml", kSmall);
  const Outcome o = ncosim({"run", file, "--threads", "300", "--runs", "300", "--periods", "20",
                            "--quiet", "--out", (dir_ / "out").string()},
                           "ulimit -v 2000000; ");
  EXPECT_EQ(o.code, 1) << o.output;
  EXPECT_NE(o.output.find("cannot start worker thread"), std::string::npos) << o.output;
  EXPECT_EQ(o.output.find("terminate called"), std::string::npos) << o.output;
}

// Finding 3: a trace link on /dev/zero grew to 4 GB and a FIFO blocked `check` forever.
TEST_F(Reliability, TraceFilesMustBeRegularAndBounded) {
  std::string text = kSmall;
  const std::string file = write("small.toml", text);
  fs::create_symlink("/dev/zero", dir_ / "trace.csv");
  Outcome o = ncosim({"check", file}, "timeout 20 ");
  EXPECT_EQ(o.code, 2) << o.output;
  EXPECT_NE(o.output.find("regular file"), std::string::npos) << o.output;
  EXPECT_NE(o.output.find(file + ":20: key 'link[0].file'"), std::string::npos) << o.output;
  fs::remove(dir_ / "trace.csv");
  ASSERT_EQ(::mkfifo((dir_ / "trace.csv").c_str(), 0600), 0);
  o = ncosim({"check", file}, "timeout 20 ");
  EXPECT_EQ(o.code, 2) << o.output;
  EXPECT_NE(o.output.find("FIFO"), std::string::npos) << o.output;
  fs::remove(dir_ / "trace.csv");
  write("trace.csv", "seq,delay\n0,1\n1," + std::string(5000, '1') + "\n");
  o = ncosim({"check", file});
  EXPECT_EQ(o.code, 2) << o.output;
  EXPECT_NE(o.output.find("trace.csv:3: line longer than 4096 bytes"), std::string::npos)
      << o.output;
  // The scenario file itself.
  o = ncosim({"check", "/dev/zero"}, "timeout 20 ");
  EXPECT_EQ(o.code, 2) << o.output;
  EXPECT_NE(o.output.find("regular scenario file"), std::string::npos) << o.output;
}

// Issue 29, finding 10: one delay of 10^8 periods passed `check`, then `run` grew 70 bytes per
// period of delay (links.csv's per-delay counts) to bad_alloc after 2.6 GB, leaving a store behind;
// 2^63 - 1 gave "vector::_M_fill_insert". The estimate counts it: refused at `check` at the
// trace's line, naming the delay, and `run` writes nothing.
TEST_F(Reliability, AHugeTraceDelayIsRefusedAtItsLineBeforeTheRuns) {
  const std::string file = write("small.toml", kSmall);
  for (const std::string delay : {"100000000", "9223372036854775807"}) {
    std::string trace = "seq,delay\n";
    for (int i = 0; i < 400; ++i) trace += fmt::format("{},{}\n", i, i == 300 ? delay : "1");
    const std::string csv = write("trace.csv", trace);
    const auto t0 = std::chrono::steady_clock::now();
    Outcome o = ncosim({"check", file}, "ulimit -v 2000000; ");
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    EXPECT_EQ(o.code, 2) << o.output;
    EXPECT_NE(o.output.find(csv + ":302: delay: " + delay + " periods"), std::string::npos)
        << o.output;
    EXPECT_NE(o.output.find("above the memory limit of 4.0 GB (--max-memory) (the trace named by " +
                            file + ":20: key 'link[0].file')"),
              std::string::npos)
        << o.output;
    EXPECT_LT(seconds, 10.0);
    const fs::path out = dir_ / "out";
    o = ncosim({"run", file, "--quiet", "--out", out.string()}, "ulimit -v 2000000; ");
    EXPECT_EQ(o.code, 2) << o.output;
    EXPECT_FALSE(fs::exists(out)) << delay;
  }
  // A raised limit lets a large delay through (it is never delivered within the run).
  std::string trace = "seq,delay\n";
  for (int i = 0; i < 400; ++i) trace += fmt::format("{},{}\n", i, i == 300 ? "100000" : "1");
  write("trace.csv", trace);
  EXPECT_EQ(ncosim({"check", file}).code, 0);
}

// Issue 29, finding 10: /proc/kmsg (a regular file of size 0 whose read blocks) hung `check`.
// Used only when it is readable and holds no pending message (nothing is consumed then).
TEST_F(Reliability, ATraceFileWhoseReadWouldBlockIsRefused) {
  const int fd = ::open("/proc/kmsg", O_RDONLY | O_NONBLOCK);
  if (fd < 0) GTEST_SKIP() << "/proc/kmsg cannot be opened here";
  pollfd p{fd, POLLIN, 0};
  const int ready = ::poll(&p, 1, 0);
  ::close(fd);
  if (ready != 0) GTEST_SKIP() << "/proc/kmsg holds pending messages (reading would consume them)";
  std::string text = kSmall;
  text.replace(text.find("file = \"trace.csv\""), 18, "file = \"/proc/kmsg\"");
  const std::string file = write("kmsg.toml", text);
  const Outcome o = ncosim({"check", file}, "timeout 20 ");
  EXPECT_EQ(o.code, 2) << o.output;
  EXPECT_NE(o.output.find(file + ":20: key 'link[0].file'"), std::string::npos) << o.output;
  EXPECT_NE(o.output.find("without waiting"), std::string::npos) << o.output;
}

// Issue 29, finding 10: trace errors printed a line's raw bytes (ESC sequences, invalid UTF-8)
// to the terminal and a NUL cut the message; they are escaped as \xNN, in `check` and `fit`.
TEST_F(Reliability, TraceErrorsEscapeTheBytesOfTheLine) {
  const std::string file = write("small.toml", kSmall);
  const std::string bad = std::string("seq,delay\n0,1\n1,\033[31mred\377\376") + '\0' + "tail\n";
  const std::string csv = write("trace.csv", bad);
  for (const auto& args : std::vector<std::vector<std::string>>{
           {"check", file}, {"fit", csv, "--out", (dir_ / "fit").string()}}) {
    const Outcome o = ncosim(args);
    EXPECT_EQ(o.code, 2) << o.output;
    EXPECT_NE(o.output.find(csv + ":3: "), std::string::npos) << o.output;
    EXPECT_NE(o.output.find("got '1,\\x1b[31mred\\xff\\xfe\\x00tail'"), std::string::npos)
        << o.output;
    EXPECT_EQ(o.output.find('\033'), std::string::npos) << o.output;
    EXPECT_EQ(o.output.find('\377'), std::string::npos) << o.output;
    EXPECT_EQ(o.output.find('\0'), std::string::npos) << o.output;
  }
}

// Finding 7: base values overridden by a sweep were never validated; the message names the
// base scenario.
TEST_F(Reliability, BaseValuesOverriddenByASweepAreValidated) {
  write("trace.csv", trace_csv(400));
  std::string text = kSmall;
  text.replace(text.find("max_delay = 1"), 13, "max_delay = inf");
  text += "[[sweep]]\nkey = \"estimator[0].max_delay\"\nvalues = [0, 1]\n";
  const std::string file = write("sweep.toml", text);
  const Outcome o = ncosim({"check", file});
  EXPECT_EQ(o.code, 2) << o.output;
  EXPECT_NE(o.output.find(file + ":24: key 'estimator[0].max_delay'"), std::string::npos)
      << o.output;
  EXPECT_NE(o.output.find("base scenario"), std::string::npos) << o.output;
  // A valid base value is not a failure.
  std::string ok = kSmall + "[[sweep]]\nkey = \"estimator[0].max_delay\"\nvalues = [0, 2]\n";
  EXPECT_EQ(ncosim({"check", write("ok.toml", ok)}).code, 0);
}

// Finding 7: --out "" silently wrote to the default folder.
TEST_F(Reliability, EmptyOutIsRefused) {
  write("trace.csv", trace_csv(400));
  const Outcome o = ncosim({"run", write("small.toml", kSmall), "--out", ""});
  EXPECT_EQ(o.code, 2) << o.output;
  EXPECT_NE(o.output.find("--out: expected a folder name"), std::string::npos) << o.output;
}

// Finding 7: a key holding NUL cut the message; any byte survives (escaped).
TEST_F(Reliability, MessagesSurviveAnyByteInAKey) {
  write("trace.csv", trace_csv(400));
  std::string text = kSmall;
  text.replace(text.find("seed = 3"), 8, "seed = 3\n\"a\\u0000b\\u0007c\" = 1");
  const std::string file = write("nul.toml", text);
  const Outcome o = ncosim({"check", file});
  EXPECT_EQ(o.code, 2) << o.output;
  EXPECT_NE(o.output.find(file + ":7: key 'run.a\\x00b\\x07c': unknown key"), std::string::npos)
      << o.output;
  EXPECT_EQ(o.output.find('\0'), std::string::npos);
}

// Finding 7: ranges stated correctly.
TEST_F(Reliability, RangesAreStatedCorrectly) {
  write("trace.csv", trace_csv(400));
  std::string text = kSmall;
  text.replace(text.find("runs = 2"), 8, "runs = 1e8");
  Outcome o = ncosim({"check", write("runs.toml", text)});
  EXPECT_EQ(o.code, 2) << o.output;
  EXPECT_NE(o.output.find("expected an integer in 1..10000000 (1e7), got 100000000"),
            std::string::npos)
      << o.output;
  text = kSmall;
  text.replace(text.find("R = [[0.01]]"), 12, "R = [[0.01]]\nevery = 1e9");
  o = ncosim({"check", write("every.toml", text)});
  EXPECT_EQ(o.code, 2) << o.output;
  EXPECT_NE(o.output.find("expected an integer in 1..1000000 (1e6), got 1000000000"),
            std::string::npos)
      << o.output;
}

// Finding 7: a missing [plant] named neither the line nor the table.
TEST_F(Reliability, AMissingRequiredTableNamesTheFileAndTheTable) {
  write("trace.csv", trace_csv(400));
  std::string text = kSmall;
  const std::size_t from = text.find("[plant]");
  text.erase(from, text.find("[[sensor]]") - from);
  const std::string file = write("noplant.toml", text);
  const Outcome o = ncosim({"check", file});
  EXPECT_EQ(o.code, 2) << o.output;
  EXPECT_NE(o.output.find(file + ":1: key 'plant': expected a [plant] table"), std::string::npos)
      << o.output;
}

// Found by the 10^6-mutant structured fuzz campaign: a [[sweep]] key below a table the file
// lacks made that table with no line, and the table's missing required key had no FILE:LINE.
TEST_F(Reliability, ATableOnlyASweepMakesNamesTheSweepsLine) {
  write("trace.csv", trace_csv(400));
  std::string text = kSmall;
  const std::size_t from = text.find("[plant]");
  text.erase(from, text.find("[[sensor]]") - from);
  text +=
      "\n[[sweep]]\nkey = \"plant.W\"\nvalues = [[[0.01, 0.0], [0.0, 0.01]], [[0.02, 0.0], [0.0, "
      "0.02]]]\n";
  const std::string file = write("sweepplant.toml", text);
  std::size_t values_line = 1;
  for (std::size_t i = 0; i < text.find("values = [[["); ++i)
    values_line += text[i] == '\n' ? 1 : 0;
  const Outcome o = ncosim({"check", file});
  EXPECT_EQ(o.code, 2) << o.output;
  EXPECT_NE(o.output.find(fmt::format("{}:{}: key 'plant.", file, values_line)), std::string::npos)
      << o.output;
}

// Finding 8: R = 0 and delta = 0 in the send-on-delta design gave design_lmi_invalid_problem,
// a status the docs called a bug.
TEST_F(Reliability, DegenerateSendOnDeltaDesignsGetAClearStatus) {
  const std::string file = (kSource / "scenarios" / "sod_example51.toml").string();
  const Outcome o = ncosim({"design", file, "--set", "sensor[0].R=[[0.0]]", "--set",
                            "sensor[1].R=[[0.0]]", "--set", "sensor[0].delta=0.0", "--set",
                            "sensor[1].delta=0.0", "--out", (dir_ / "d").string()});
  EXPECT_EQ(o.code, 0) << o.output;
  EXPECT_EQ(o.output.find("invalid_problem"), std::string::npos) << o.output;
  const std::string readme =
      ncosim::testing::read_text((kSource / "results" / "README.md").string());
  EXPECT_EQ(readme.find("a bug"), std::string::npos);
}

// Found by the 10^6-mutant structured fuzz campaign: a plant Bw entry of 1e300 in
// sod_example51 made the sod_jump LMI designs loop in CSDP without end (`check` ran for more
// than 60 s, the fuzzer's mutant for minutes). The LMI data are now refused above 1e100: the
// designs end at once with status lmi_invalid_problem and a message that says to rescale.
TEST_F(Reliability, BadlyScaledModelEndsTheLmiDesignWithAMessage) {
  const std::string file = (kSource / "scenarios" / "sod_example51.toml").string();
  const auto t0 = std::chrono::steady_clock::now();
  const Outcome o = ncosim(
      {"design", file, "--set", "plant.Bw=[[-0.229, 0.023], [0.231, 1e300], [-0.186, 0.245]]",
       "--out", (dir_ / "d").string()},
      "timeout 60 ");
  EXPECT_LT(std::chrono::steady_clock::now() - t0, std::chrono::seconds(30));
  ASSERT_EQ(o.code, 0) << o.output;
  const std::string json = ncosim::testing::read_text((dir_ / "d" / "design.json").string());
  EXPECT_NE(json.find("\"status\": \"lmi_invalid_problem\""), std::string::npos);
  EXPECT_NE(json.find("rescale the model"), std::string::npos);
}

// Found by the 10^6-mutant structured fuzz campaign: a plant Bw entry of 1e6 in Table 2's
// scenario made two S3 designs iterate to their 200 000-iteration cap (16 s of CPU for `check`,
// silent, far past the resource estimate's ~50 iterations): the relative change had stalled at
// ~1e-8, rounding noise of the badly scaled model, far above the 1e-13 tolerance. The iteration
// now stops when the relative change, below 1e-6, no longer decreases (a window of 2000
// iterations without a 10 % improvement on the previous one) and design.json says why.
TEST_F(Reliability, BadlyScaledModelStopsAStalledJumpIterationWithAMessage) {
  const std::string file = (kSource / "scenarios" / "dolz2014_table2.toml").string();
  const auto t0 = std::chrono::steady_clock::now();
  const Outcome o = ncosim({"design", file, "--set", "plant.Bw=[[0.0121, 0.1347], [1e6, 0.0831]]",
                            "--out", (dir_ / "d").string()},
                           "timeout 60 ");
  EXPECT_LT(std::chrono::steady_clock::now() - t0,
            std::chrono::seconds(8));  // 16 s of CPU before, 0.4 s after
  ASSERT_EQ(o.code, 0) << o.output;
  const auto design =
      nlohmann::json::parse(ncosim::testing::read_text((dir_ / "d" / "design.json").string()));
  int stalled = 0;
  for (const auto& e : design["estimators"]) {
    if (e["status"] != "not_converged") continue;
    ++stalled;
    EXPECT_LT(e["iterations"].get<int>(), 200000) << e["name"];
    EXPECT_NE(e.value("iteration_message", "").find("stalled at"), std::string::npos) << e["name"];
  }
  EXPECT_GE(stalled,
            1);  // here the two S3 designs (S1, S2 and S4 converge); rounding decides which
}

// Peak RSS (kB) of `ncosim ARGS` alone: the child's own rusage (wait4), the shell replaced by exec.
long peak_rss_kb(const std::vector<std::string>& args) {
  const std::string cmd = "exec " + ncosim::testing::ncosim_command(args) + " >/dev/null 2>&1";
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::execl("/bin/sh", "sh", "-c", cmd.c_str(), static_cast<char*>(nullptr));
    ::_exit(127);
  }
  int status = 0;
  struct rusage usage {};
  if (pid < 0 || ::wait4(pid, &status, 0, &usage) != pid || !WIFEXITED(status) ||
      WEXITSTATUS(status) != 0)
    return -1;
  return usage.ru_maxrss;
}

// Issue 18's acceptance (finding 5): the peak RSS of one run does not grow with its periods
// (10^5 against 10^7 within 10 %). The per-period metrics are summed as the run goes; the
// timing replay (on by default) logs at most kReplayPeriods periods. Measured 14.2 and 16.6 MB
// with a cap of 10 000 logged periods (17 %), 14.8 and 16.8 MB at 5000, 13.7 and 13.8 MB with
// --no-timing.
TEST_F(Reliability, PeakMemoryOfARunDoesNotGrowWithItsPeriods) {
  const std::string file = (kSource / "tests" / "cli" / "data" / "base.toml").string();
  auto rss = [&](const std::string& periods) {
    return peak_rss_kb({"run", file, "--runs", "1", "--periods", periods, "--threads", "1",
                        "--quiet", "--out", (dir_ / ("p" + periods)).string()});
  };
  const long short_run = rss("100000");
  const long long_run = rss("10000000");
  ASSERT_GT(short_run, 0);
  ASSERT_GT(long_run, 0);
  EXPECT_LT(static_cast<double>(long_run), 1.10 * static_cast<double>(short_run))
      << "peak RSS " << short_run << " kB at 10^5 periods, " << long_run << " kB at 10^7";
}

// Finding 5, the runs' half: 10^7 runs of 2 periods grew past 990 MB. The exports derive every
// run from the store, so a campaign's memory grows with its runs (about 1.3 kB per run here);
// it is estimated before the campaign and refused beyond --max-memory, naming run.runs.
TEST_F(Reliability, TheRunsOfACampaignAreBoundedByTheMemoryLimit) {
  const std::string file = (kSource / "tests" / "cli" / "data" / "base.toml").string();
  const auto t0 = std::chrono::steady_clock::now();
  const Outcome o = ncosim({"run", file, "--runs", "10000000", "--periods", "200", "--quiet",
                            "--out", (dir_ / "out").string()});
  EXPECT_LT(std::chrono::steady_clock::now() - t0, std::chrono::seconds(10));
  EXPECT_EQ(o.code, 2) << o.output;
  EXPECT_NE(
      o.output.find(
          "base.toml:5: key 'run.runs': the campaign keeps per-run results of 10000000 runs x 1 "
          "case(s) x 2 estimator(s): an estimated 11.1 GB, above the memory limit of 4.0 GB "
          "(--max-memory)"),
      std::string::npos)
      << o.output;
  EXPECT_FALSE(fs::exists(dir_ / "out" / "runs.sqlite"));
}

// Finding 4: the result set of `run` is atomic as a whole: a kill before any step of the write
// sequence leaves the previous set or the complete new one, and the next run cleans up. The run
// store is part of the set (issue 29, finding 2): its inode is checked like every export's.
TEST_F(Reliability, KilledRunLeavesThePreviousOrTheNewSet) {
  write("trace.csv", trace_csv(400));
  const std::string file = write("small.toml", kSmall);
  const fs::path out = dir_ / "out";
  auto run = [&](const std::string& seed, const std::string& env) {
    // --replace: each run deliberately replaces the other seed's campaign (issue 28, part 3).
    return ncosim({"run", file, "--seed", seed, "--quiet", "--replace", "--out", out.string()},
                  env);
  };
  // A set is identified by its files' inodes (every write makes new files; timing columns make
  // contents differ between identical campaigns) and by runs.csv, which depends on the seed only.
  struct Set {
    std::map<std::string, ino_t> inodes;
    std::string runs;
  };
  auto snapshot = [&] {
    Set s;
    for (const auto& e : fs::directory_iterator(out)) {
      struct stat st {};
      ::stat(e.path().c_str(), &st);
      s.inodes[e.path().filename().string()] = st.st_ino;
    }
    s.runs = ncosim::testing::read_text((out / "runs.csv").string());
    return s;
  };
  ASSERT_EQ(run("2", "").code, 0);
  const std::string runs_of_seed2 = snapshot().runs;
  ASSERT_EQ(run("1", "").code, 0);
  int kills = 0, mixed = 0;
  for (int k = 1; k < 80; ++k) {
    const Set before = snapshot();
    const Outcome o = run("2", fmt::format("NCOSIM_TEST_KILL_AT={} ", k));
    if (o.code == 0) break;
    ++kills;
    const Set now = snapshot();
    ASSERT_EQ(now.inodes.size(), before.inodes.size()) << "kill before step " << k;
    int old_files = 0, new_files = 0;
    for (const auto& [name, inode] : now.inodes) {
      ASSERT_EQ(before.inodes.count(name), 1u) << name;
      (before.inodes.at(name) == inode ? old_files : new_files)++;
    }
    const bool whole = (new_files == 0 && now.runs == before.runs) ||
                       (old_files == 0 && now.runs == runs_of_seed2);
    if (!whole) ++mixed;
    EXPECT_TRUE(whole) << "kill before step " << k << ": " << old_files << " old and " << new_files
                       << " new files";
    ASSERT_EQ(run("1", "").code, 0);  // recovers, cleans, and writes the seed-1 set again
  }
  EXPECT_GE(kills, 15);
  EXPECT_EQ(mixed, 0);
  for (const auto& e : fs::directory_iterator(dir_)) {
    const std::string n = e.path().filename().string();
    EXPECT_TRUE(n == "out" || n == ".out.lock" || n == "small.toml" || n == "trace.csv") << n;
  }
}

}  // namespace
