// tests/config/config_test.cc — the configuration layer in process (linked alone, without the
// application): typed reading of tables with FILE:LINE errors, unknown keys, the registry
// template's lookup, and key paths (--set, sweeps). Every expected message is written out.
#include "config/config.h"

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "config/registry.h"
#include "config/toml_path.h"
#include "error_of.h"

namespace ncosim::config {
namespace {

using testing::error_of;
toml::table parse(const std::string& text) { return testing::parse_toml(text); }

TEST(Table, ReadsTypedValuesAndDefaults) {
  const toml::table doc = parse("a = 2\nb = 0.5\nc = \"x\"\nm = [[1, 2], [3, 4]]\n[t]\nk = true\n");
  const Table root(doc, "", "s.toml");
  EXPECT_EQ(root.integer("a"), 2);
  EXPECT_EQ(root.number("a"), 2.0);  // an integer is a number
  EXPECT_EQ(root.number("b"), 0.5);
  EXPECT_EQ(root.string("c"), "x");
  EXPECT_EQ(root.integer_or("missing", 7), 7);
  EXPECT_EQ(root.choice_or("c", "y", {"x", "y"}), "x");
  const Eigen::MatrixXd m = root.matrix("m");
  ASSERT_EQ(m.rows(), 2);
  ASSERT_EQ(m.cols(), 2);
  EXPECT_EQ(m(1, 0), 3.0);
  EXPECT_TRUE(root.table("t").boolean_or("k", false));
  EXPECT_FALSE(root.opt_table("u").has_value());
}

TEST(Table, TypeErrorsNameFileLineKeyAndWhatWasFound) {
  const toml::table doc = parse("title = \"t\"\n\n[run]\nruns = \"ten\"\nperiod = 1.5\n");
  const Table run = Table(doc, "", "s.toml").table("run");
  // `runs` is on line 4, inside [run]: the path is run.runs.
  EXPECT_EQ(error_of([&] { (void)run.integer("runs"); }),
            "s.toml:4: key 'run.runs': expected an integer, got a string \"ten\"");
  EXPECT_EQ(error_of([&] { (void)run.integer("period"); }),
            "s.toml:5: key 'run.period': expected an integer, got 1.5");
  // A missing required key is reported at its table's line (3).
  EXPECT_EQ(error_of([&] { (void)run.string("seed"); }),
            "s.toml:3: key 'run.seed': expected a string, got nothing (the key is required)");
}

TEST(Table, ChoiceErrorListsTheChoicesAndTheClosestOne) {
  const toml::table doc = parse("mode = \"alwys\"\n");
  const Table root(doc, "", "s.toml");
  EXPECT_EQ(error_of([&] {
              (void)root.choice_or("mode", "auto", {"auto", "always", "never"});
            }),
            "s.toml:1: key 'mode': expected one of \"auto\", \"always\", \"never\", got \"alwys\" "
            "(did you mean "
            "\"always\"?)");
}

TEST(Table, FinishRejectsKeysNoReaderAskedFor) {
  const toml::table doc = parse("[[link]]\nname = \"a\"\nkindd = \"delay\"\n");
  const auto links = Table(doc, "", "s.toml").tables("link");
  ASSERT_EQ(links.size(), 1u);
  (void)links[0].string("name");
  links[0].allow("kind");
  // `kindd` (line 3) was not read; `kind` is the closest known key.
  EXPECT_EQ(error_of([&] { links[0].finish(); }),
            "s.toml:3: key 'link[0].kindd': unknown key (did you mean 'kind'?)");
  const toml::table ok = parse("[[link]]\nname = \"a\"\n");
  const auto ok_links = Table(ok, "", "s.toml").tables("link");
  (void)ok_links[0].string("name");
  EXPECT_EQ(error_of([&] { ok_links[0].finish(); }), "");
}

TEST(Table, RangeHelpersFailAtTheKey) {
  const toml::table doc = parse("p = 1.5\npmf = [0.7, 0.5]\nW = [[1, 2], [0, 1]]\n");
  const Table root(doc, "", "s.toml");
  EXPECT_EQ(error_of([&] { require_probability(root, "p", root.number("p")); }),
            "s.toml:1: key 'p': expected a probability in [0, 1], got 1.5");
  EXPECT_EQ(error_of([&] { require_subprobability(root, "pmf", root.numbers("pmf")); }),
            "s.toml:2: key 'pmf': probabilities must sum to <= 1, got 1.2");
  EXPECT_EQ(error_of([&] { require_psd(root, "W", root.matrix("W")); }),
            "s.toml:3: key 'W': expected a symmetric positive semidefinite matrix, got a "
            "non-symmetric one");
}

TEST(FormatError, OmitsWhatIsUnknownAndEscapesUnprintableBytes) {
  EXPECT_EQ(format_error("f.toml", 3, "a.b", "m"), "f.toml:3: key 'a.b': m");
  EXPECT_EQ(format_error("f.toml", 0, "", "m"), "f.toml: m");
  EXPECT_EQ(format_error("", 0, "k", "m"), "key 'k': m");
  EXPECT_EQ(format_error("f.toml", 1, std::string("a\x01", 2), "m"), "f.toml:1: key 'a\\x01': m");
}

TEST(Registry, LookupFindsTheKindOrListsTheValidOnes) {
  Registry<int, int> r;
  r.add("double", "2x", [](const Table&, int x) { return 2 * x; });
  r.add("triple", "3x", [](const Table&, int x) { return 3 * x; });
  const toml::table doc = parse("kind = \"triple\"\n[bad]\nkind = \"tripel\"\n");
  const Table root(doc, "", "s.toml");
  EXPECT_EQ(r.lookup(root, "kind", "").factory(root, 5), 15);
  EXPECT_EQ(r.lookup(root.table("bad"), "absent", "double").name, "double");  // the fallback
  EXPECT_EQ(error_of([&] { (void)r.lookup(root.table("bad"), "kind", ""); }),
            "s.toml:3: key 'bad.kind': expected one of \"double\", \"triple\", got \"tripel\" (did "
            "you mean "
            "\"triple\"?)");
  EXPECT_EQ(r.names(), (std::vector<std::string>{"double", "triple"}));
}

TEST(TomlPath, SetCreatesTablesAndReplacesArrayElements) {
  toml::table doc = parse("[[estimator]]\nhistory = 2\n[[estimator]]\nhistory = 3\n");
  apply_set(doc, "estimator[1].history = 9", "--set");
  apply_set(doc, "run.runs=4", "--set");
  EXPECT_EQ(find_path(doc, "estimator[1].history")->value<std::int64_t>(), 9);
  EXPECT_EQ(find_path(doc, "estimator[0].history")->value<std::int64_t>(), 2);
  EXPECT_EQ(find_path(doc, "run.runs")->value<std::int64_t>(), 4);
  EXPECT_EQ(find_path(doc, "run.seed"), nullptr);
  EXPECT_EQ(find_path(doc, "estimator[5].history"), nullptr);
  EXPECT_EQ(find_path(doc, "estimator[x"), nullptr);  // malformed: nothing, not an error
  // A value set on the command line carries its origin, so later errors name the option.
  const Table run = Table(doc, "", "s.toml").table("run");
  EXPECT_EQ(error_of([&] { (void)run.string("runs"); }),
            "--set: key 'run.runs': expected a string, got 4");
}

TEST(TomlPath, BadPathsAndValuesNameTheOrigin) {
  toml::table doc = parse("[[estimator]]\nhistory = 2\n");
  EXPECT_EQ(error_of([&] { apply_set(doc, "estimator[3].history=1", "--set"); }),
            "--set: key 'estimator[3].history': there is no [[estimator]] number 3 (the scenario "
            "has 1; indices "
            "are 0-based)");
  EXPECT_EQ(error_of([&] { apply_set(doc, "run.runs", "--set"); }),
            "--set: expected KEY=VALUE, got 'run.runs'");
  EXPECT_EQ(error_of([&] { apply_set(doc, "estimator[a].history=1", "--set"); }),
            "--set: key 'estimator[a].history': expected a 0-based index inside [], got 'a'");
  EXPECT_EQ(
      error_of([&] { apply_set(doc, "run..runs=1", "--set"); }),
      "--set: key 'run..runs': expected a key path like 'estimator[0].history' or 'run.runs'");
  EXPECT_NE(error_of([&] { apply_set(doc, "run.runs=[1,", "--set"); })
                .find("--set: key 'run.runs': expected a TOML value (e.g. 4, 0.5, \"S4\", [0.9, "
                      "0.05]), got '[1,'"),
            std::string::npos);
  // A scalar on the way is not a table: the file's line is given by set_path's caller.
  EXPECT_EQ(error_of([&] {
              set_path(doc, "estimator[0].history.x", toml::value<std::int64_t>(1), "s.toml", 7);
            }),
            "s.toml:7: key 'estimator[0].history.x': 'estimator[0].history' is not a table");
}

}  // namespace
}  // namespace ncosim::config
