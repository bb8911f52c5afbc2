// tests/cli/fit_cli_test.cc — `ncosim fit` reads like a fit (issue 40): an EM stopped at its
// iteration cap is said not to have converged (printed, fit.csv, fit.json) and is not selected;
// a 3-state fit of a long delay law prints a short summary whose every interval is an interval
// (the full detail in fit.json and with --verbose); a bad --max-iterations is exit 2, nothing
// written.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <nlohmann/json.hpp>
#include <regex>

#include "cli/temp_dir_test.h"
#include "test_util.h"

namespace {

namespace fs = std::filesystem;
using Outcome = ncosim::testing::CommandOutcome;
using ncosim::testing::run_ncosim;
using ncosim::testing::split_lines;

class FitCli : public ncosim::testing::TempDirTest {
 protected:
  FitCli() : TempDirTest("ncosim_fit_") {}
  // Bursty losses: 40 packets delivered (delay 0, now and then 1), then 10 lost, repeated.
  std::string bursty() {
    std::string trace = "seq,delay\n";
    for (int i = 0; i < 5000; ++i)
      trace += fmt::format("{},{}\n", i, i % 50 >= 40 ? "" : (i % 7 == 0 ? "1" : "0"));
    return write("bursty.csv", trace);
  }
  nlohmann::json family(const fs::path& out, const std::string& name) {
    const auto j = nlohmann::json::parse(ncosim::testing::read_text((out / "fit.json").string()));
    for (const auto& f : j["families"]) {
      if (f["family"] == name) return f;
    }
    ADD_FAILURE() << "no family " << name;
    return {};
  }
  // The line of the family table that starts with `name`.
  static std::string table_row(const std::string& output, const std::string& name) {
    for (const auto& l : split_lines(output)) {
      if (l.rfind(name + " ", 0) == 0) return l;
    }
    return "";
  }
};

TEST_F(FitCli, AnEmStoppedAtItsCapIsNotConvergedAndNotSelected) {
  const std::string trace = bursty();
  const fs::path out = dir_ / "capped";
  const Outcome o = run_ncosim({"fit", trace, "--out", out.string(), "--family", "delay",
                                "--family", "gilbert_elliott", "--max-iterations", "2"});
  ASSERT_EQ(o.code, 0) << o.output;
  const std::string row = table_row(o.output, "gilbert_elliott");
  EXPECT_NE(row.find(" NO "), std::string::npos) << o.output;
  EXPECT_EQ(row.find("yes"), std::string::npos) << o.output;
  EXPECT_EQ(row.find("<-"), std::string::npos) << o.output;  // not selected
  EXPECT_NE(o.output.find("gilbert_elliott: not converged: the EM stopped at its cap of 2 "
                          "iterations"),
            std::string::npos)
      << o.output;
  EXPECT_NE(o.output.find("delay, selected by bic"), std::string::npos) << o.output;
  EXPECT_EQ(o.output.find("gilbert_elliott, selected"), std::string::npos) << o.output;
  const auto ge = family(out, "gilbert_elliott");
  EXPECT_EQ(ge["converged"], false);
  EXPECT_EQ(ge["selected"], false);
  EXPECT_EQ(ge["iteration_cap"], 2);
  EXPECT_NE(ge["note"].get<std::string>().find("not converged"), std::string::npos);
  const auto csv = split_lines(ncosim::testing::read_text((out / "fit.csv").string()));
  EXPECT_NE(std::find(csv.begin(), csv.end(), "gilbert_elliott,fit,converged,0,,,,"), csv.end());
  EXPECT_NE(ncosim::testing::read_text((out / "link.toml").string()).find("kind = \"delay\""),
            std::string::npos);
  // The same trace without the cap: converged, and (the chain explains the bursts) selected.
  const fs::path free = dir_ / "free";
  const Outcome f = run_ncosim(
      {"fit", trace, "--out", free.string(), "--family", "delay", "--family", "gilbert_elliott"});
  ASSERT_EQ(f.code, 0) << f.output;
  EXPECT_NE(table_row(f.output, "gilbert_elliott").find(" yes "), std::string::npos) << f.output;
  EXPECT_NE(f.output.find("gilbert_elliott, selected by bic"), std::string::npos) << f.output;
  EXPECT_EQ(family(free, "gilbert_elliott")["converged"], true);
}

// A 3-state Markov fit of 40 delay values: the issue's fit printed about 2000 lines, with
// intervals [x, x]. Now a summary of a few dozen lines, every interval printed a true interval.
TEST_F(FitCli, ALongDelayLawIsSummarisedAndItsIntervalsAreIntervals) {
  std::string trace = "seq,delay\n";
  std::uint64_t x = 12345;
  for (int i = 0; i < 12000; ++i) {
    x = x * 6364136223846793005ULL + 1442695040888963407ULL;
    const int u = static_cast<int>((x >> 33) % 1000);
    const bool slow = (i / 300) % 3 == 2;  // one block in three is congested
    const std::string d = u < (slow ? 150 : 10) ? ""
                          : slow                ? std::to_string(5 + u % 35)
                                                : std::to_string(u % 3);
    trace += fmt::format("{},{}\n", i, d);
  }
  const std::string file = write("long.csv", trace);
  const fs::path out = dir_ / "long";
  const Outcome o = run_ncosim({"fit", file, "--out", out.string(), "--family", "markov3"});
  ASSERT_EQ(o.code, 0) << o.output;
  const auto lines = split_lines(o.output);
  EXPECT_LT(lines.size(), 40U) << o.output;
  EXPECT_NE(o.output.find("more: delay_pmf, in fit.json and fit.csv; --verbose prints them"),
            std::string::npos)
      << o.output;
  const std::regex interval(R"(\[([-0-9.e+]+), ([-0-9.e+]+)\])");
  int intervals = 0;
  for (const auto& l : lines) {
    std::smatch m;
    if (l.rfind("  ", 0) != 0 || !std::regex_search(l, m, interval)) continue;
    ++intervals;
    EXPECT_LT(std::stod(m[1]), std::stod(m[2])) << l;
  }
  EXPECT_GE(intervals, 15) << o.output;  // 9 transitions, 3 losses, 3 mean delays
  const auto m3 = family(out, "markov3");
  int finite = 0;
  for (const auto& p : m3["params"]) finite += p["ci95_low"].is_number() ? 1 : 0;
  EXPECT_EQ(finite, static_cast<int>(m3["params"].size()));
  const Outcome v =
      run_ncosim({"fit", file, "--out", (dir_ / "v").string(), "--family", "markov3", "--verbose"});
  ASSERT_EQ(v.code, 0) << v.output;
  EXPECT_NE(v.output.find("  delay_pmf[2][38]"), std::string::npos) << v.output;
}

// Three hidden states fitted to independent packets: the states are not identified and no
// interval can be computed. The reason is said once, not on each of the 21 lines.
TEST_F(FitCli, AReasonForNoIntervalIsSaidOnce) {
  std::string trace = "seq,delay\n";
  std::uint64_t x = 777;
  for (int i = 0; i < 3000; ++i) {
    x = x * 6364136223846793005ULL + 1442695040888963407ULL;
    const int u = static_cast<int>((x >> 33) % 1000);
    trace += fmt::format("{},{}\n", i, u < 100 ? "" : u < 300 ? "1" : "0");
  }
  const std::string file = write("iid.csv", trace);
  const Outcome o = run_ncosim(
      {"fit", file, "--out", (dir_ / "iid").string(), "--family", "markov3", "--verbose"});
  ASSERT_EQ(o.code, 0) << o.output;
  int said = 0, as_above = 0;
  for (const auto& l : split_lines(o.output)) {
    if (l.rfind("  ", 0) != 0) continue;  // the parameter lines
    said += l.find("the observed information is singular") != std::string::npos ? 1 : 0;
    as_above += l.find("(no interval, as above)") != std::string::npos ? 1 : 0;
  }
  EXPECT_EQ(said, 1) << o.output;
  EXPECT_EQ(as_above, 20) << o.output;  // 9 + 3 + 6 parameters and 3 mean delays, less the first
}

TEST_F(FitCli, ABadMaxIterationsIsRefusedAndNothingIsWritten) {
  const std::string trace = bursty();
  for (const std::string bad : {"0", "-3", "x", "2000000"}) {
    const fs::path out = dir_ / "bad";
    const Outcome o = run_ncosim({"fit", trace, "--out", out.string(), "--max-iterations", bad});
    EXPECT_EQ(o.code, 2) << bad << ": " << o.output;
    EXPECT_NE(o.output.find("--max-iterations"), std::string::npos) << o.output;
    EXPECT_FALSE(fs::exists(out)) << bad;
  }
}

}  // namespace
