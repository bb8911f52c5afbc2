// tests/cli/every_error_test.cc — every independent error of a scenario at once (issue 40 part 4,
// sim/scenario/scenario_check.h): `check` and `run` report every key-level error of the file, one
// line each in file order with its FILE:LINE and did-you-mean, up to 20 and then how many more,
// exit 2, nothing written; errors that need the model come one at a time, after them.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <string>
#include <vector>

#include "temp_dir_test.h"
#include "test_util.h"

namespace ncosim::testing {
namespace {

namespace fs = std::filesystem;

class EveryError : public TempDirTest {
 protected:
  EveryError() : TempDirTest("ncosim_every_error_") {}
  void SetUp() override {
    TempDirTest::SetUp();
    base_ = read_text(source_path("tests/cli/data/base.toml"));
  }
  // The base scenario with each (old, new) edit applied once.
  std::string edited(const std::vector<std::pair<std::string, std::string>>& edits) const {
    std::string text = base_;
    for (const auto& [from, to] : edits) {
      const auto at = text.find(from);
      EXPECT_NE(at, std::string::npos) << from;
      if (at != std::string::npos) text.replace(at, from.size(), to);
    }
    return text;
  }
  // The 1-based line of the first occurrence of `needle` in `text`.
  static int line_of(const std::string& text, const std::string& needle) {
    const auto at = text.find(needle);
    return at == std::string::npos
               ? 0
               : 1 + static_cast<int>(std::count(text.begin(), text.begin() + at, '\n'));
  }
  std::string base_;
};

// Three typos and two bad values in five tables: one run of check names all five, in file order.
TEST_F(EveryError, CheckAndRunReportEveryKeyErrorOfTheFileAtOnce) {
  const std::string text = edited({{"seed = 7", "sed = 7"},
                                   {"kind = \"lti\"", "kind = \"ltx\""},
                                   {"R = [[0.02]]", "R = \"big\""},
                                   {"loss = 0.2", "loss = 1.2"},
                                   {"history = 2", "histroy = 2"}});
  const std::string file = write("typos.toml", text);
  const std::vector<std::string> expected{
      fmt::format("ncosim: {}:{}: key 'run.sed': unknown key (did you mean 'seed'?)", file,
                  line_of(text, "sed = 7")),
      fmt::format("ncosim: {}:{}: key 'plant.kind': expected one of \"lti\", \"lti_continuous\", "
                  "\"jump_linear\", \"transfer_function\"",
                  file, line_of(text, "kind = \"ltx\"")),
      fmt::format("ncosim: {}:{}: key 'sensor[1].R': expected a matrix [[...], ...], got a "
                  "string \"big\"",
                  file, line_of(text, "R = \"big\"")),
      fmt::format("ncosim: {}:{}: key 'link[1].loss': expected a probability in [0, 1], got 1.2",
                  file, line_of(text, "loss = 1.2")),
      fmt::format("ncosim: {}:{}: key 'estimator[0].histroy': unknown key (did you mean "
                  "'history'?)",
                  file, line_of(text, "histroy = 2")),
  };
  for (const char* command : {"check", "run"}) {
    const fs::path out = dir_ / "out";
    std::vector<std::string> args{command, file};
    if (std::string(command) == "run") args.insert(args.end(), {"--out", out.string(), "--quiet"});
    const CommandOutcome o = run_ncosim(args);
    EXPECT_EQ(o.code, 2) << command << "\n" << o.output;
    const std::vector<std::string> lines = split_lines(o.output);
    ASSERT_EQ(lines.size(), expected.size()) << command << "\n" << o.output;
    for (std::size_t i = 0; i < expected.size(); ++i)
      EXPECT_EQ(lines[i].substr(0, expected[i].size()), expected[i]) << command;
    EXPECT_FALSE(fs::exists(out)) << "run wrote its folder";
  }
}

// A typo of a required key is one error (at the typo, with its did-you-mean), not also "the key
// is required": three typos in three sections, three lines.
TEST_F(EveryError, ATypoOfARequiredKeyIsOneError) {
  const std::string text =
      edited({{"seed = 7", "sed = 7"}, {"std = 1.0", "sdt = 1.0"}, {"history = 2", "histroy = 2"}});
  const std::string file = write("three.toml", text);
  const CommandOutcome o = run_ncosim({"check", file});
  EXPECT_EQ(o.code, 2) << o.output;
  const std::vector<std::string> expected{
      fmt::format("ncosim: {}:{}: key 'run.sed': unknown key (did you mean 'seed'?)", file,
                  line_of(text, "sed = 7")),
      fmt::format("ncosim: {}:{}: key 'input.sdt': unknown key (did you mean 'std'?)", file,
                  line_of(text, "sdt = 1.0")),
      fmt::format("ncosim: {}:{}: key 'estimator[0].histroy': unknown key (did you mean "
                  "'history'?)",
                  file, line_of(text, "histroy = 2")),
  };
  EXPECT_EQ(split_lines(o.output), expected) << o.output;
}

// A file with 25 unknown keys: the first 20, then a line counting the rest.
TEST_F(EveryError, ManyErrorsAreCappedWithACount) {
  std::string keys;
  for (int i = 0; i < 25; ++i) keys += fmt::format("bogus_{:02d} = {}\n", i, i);
  const std::string text = edited({{"seed = 7\n", "seed = 7\n" + keys}});
  const std::string file = write("many.toml", text);
  const CommandOutcome o = run_ncosim({"check", file});
  EXPECT_EQ(o.code, 2) << o.output;
  const std::vector<std::string> lines = split_lines(o.output);
  ASSERT_EQ(lines.size(), 21U) << o.output;
  EXPECT_EQ(lines[0], fmt::format("ncosim: {}:{}: key 'run.bogus_00': unknown key (valid keys "
                                  "here: error_curve, period, periods, recentre, runs, seed, "
                                  "warmup)",
                                  file, line_of(text, "bogus_00")));
  EXPECT_NE(lines[19].find("key 'run.bogus_19'"), std::string::npos) << lines[19];
  EXPECT_EQ(lines[20], "ncosim: and 5 more errors (25 in all; the first 20 are shown)");
}

// Errors that need the model come after the key errors are fixed, the first one alone: a plant of
// the wrong size makes both sensors' C the wrong size, and only the first is told.
TEST_F(EveryError, ModelErrorsComeOneAtATimeAfterTheKeyErrors) {
  const std::string text = edited({{"A  = [[0.9, 0.1], [0.0, 0.8]]", "A  = [[0.9]]"}});
  const std::string file = write("model.toml", text);
  const CommandOutcome o = run_ncosim({"check", file});
  EXPECT_EQ(o.code, 2) << o.output;
  EXPECT_EQ(split_lines(o.output).size(), 1U) << o.output;
  // With a key error as well, only the key error is told (the model's may follow from it).
  const std::string both =
      edited({{"A  = [[0.9, 0.1], [0.0, 0.8]]", "A  = [[0.9]]"}, {"history = 2", "history = 0"}});
  const CommandOutcome o2 = run_ncosim({"check", write("both.toml", both)});
  EXPECT_EQ(o2.code, 2) << o2.output;
  const std::vector<std::string> lines = split_lines(o2.output);
  ASSERT_EQ(lines.size(), 1U) << o2.output;
  EXPECT_NE(lines[0].find("key 'estimator[0].history': expected an integer in 1..1000, got 0"),
            std::string::npos)
      << lines[0];
}

// A required key that only a sweep gives is not missing; a bad value written outside the sweep
// is an error even where a sweep replaces it, and says so.
TEST_F(EveryError, SweptKeysAreJudgedAsTheSweepSetsThem) {
  const std::string swept =
      edited({{"A  = [[0.9, 0.1], [0.0, 0.8]]\n", ""}}) +
      "\n[[sweep]]\nkey = \"plant.A\"\nvalues = [[[0.9, 0.1], [0.0, 0.8]], [[0.5, 0.1], [0.0, "
      "0.5]]]\n";
  const CommandOutcome ok = run_ncosim({"check", write("swept.toml", swept)});
  EXPECT_EQ(ok.code, 0) << ok.output;
  const std::string bad = edited({{"history = 2", "history = 0"}}) +
                          "\n[[sweep]]\nkey = \"estimator[0].history\"\nvalues = [1, 2]\n";
  const CommandOutcome o = run_ncosim({"check", write("bad_base.toml", bad)});
  EXPECT_EQ(o.code, 2) << o.output;
  EXPECT_NE(o.output.find("key 'estimator[0].history': expected an integer in 1..1000, got 0 (in "
                          "the base scenario: the values written outside [[sweep]] must be valid "
                          "too, even where a sweep replaces them)"),
            std::string::npos)
      << o.output;
}

}  // namespace
}  // namespace ncosim::testing
