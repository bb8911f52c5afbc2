// tests/config/key_check_test.cc — every key-level error of a table at once (config/key_check.h):
// each message is the KeyReader getter's own, unknown keys all reported with a did-you-mean among
// the declared keys, fields tables checked within, keys another source sets not required; the
// array shapes (entries, columns) and words of a declaration; ScenarioError's several messages and
// their cap. Every expected message is written out.
#include "config/key_check.h"

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "error_of.h"

namespace ncosim::config {
namespace {

using testing::error_of;
toml::table parse(const std::string& text) { return testing::parse_toml(text); }

const Keys& inner_keys() {
  static const Keys keys{
      Key::number("gain").min(0.0).help("a gain"),
      Key::string("name").optional("none").help("a name"),
  };
  return keys;
}

const Keys& demo_keys() {
  static const Keys keys{
      Key::number("loss").probability().or_default(0.0).help("probability that a packet is lost"),
      Key::integer("delay").range(0, 1000).or_default(2).unit("periods").help("the delay"),
      Key::string("file").help("a file"),
      Key::numbers("position").entries(3).optional("[0, 0, 0]").help("x, y, z"),
      Key::matrix("rows").columns(3).optional("none").help("rows of x, y, z"),
      Key::number("rate")
          .above(0.0)
          .or_words({"saturated"})
          .says("a rate > 0 or \"saturated\"")
          .optional("none")
          .help("a rate"),
      Key::array("values").entries(1, 0).optional("none").help("values"),
      Key::table("inner").fields(inner_keys()).optional("none").help("a table"),
      Key::tables("many").fields(inner_keys()).entries(1, 2).optional("none").help("tables"),
  };
  return keys;
}

std::vector<std::string> errors_of(const std::string& text, bool closed = true,
                                   const KeyCheckOptions& options = {}) {
  const toml::table doc = parse(text);
  const Table t(doc, "link[0]", "s.toml");
  std::vector<LineError> errors;
  check_table(t, demo_keys(), closed, options, errors);
  return in_file_order(std::move(errors));
}

TEST(KeyCheck, AValidTableHasNoErrors) {
  EXPECT_EQ(errors_of("file = \"x\"\nposition = [1, 2, 3]\nrate = \"saturated\"\n"
                      "values = [1, \"a\"]\ninner = { gain = 1 }\n[[many]]\ngain = 2\n"),
            std::vector<std::string>{});
  EXPECT_EQ(errors_of("file = \"x\"\nrate = 5\nrows = [[1, 2, 3], [4, 5, 6]]\n"),
            std::vector<std::string>{});
}

TEST(KeyCheck, EveryErrorOfTheTableInFileOrder) {
  const std::vector<std::string> expected{
      "s.toml:1: key 'link[0].los': unknown key (did you mean 'loss'?)",
      "s.toml:2: key 'link[0].delay': expected an integer in 0..1000, got 1001",
      "s.toml:3: key 'link[0].position': expected 3 numbers, got 2 numbers",
      "s.toml:4: key 'link[0].rate': expected a rate > 0 or \"saturated\", got a string "
      "\"SATURATED\" (did you mean \"saturated\"?)",
      "s.toml:5: key 'link[0].values': expected at least 1 value, got 0 values",
      "s.toml:6: key 'link[0].rows': expected rows of 3 numbers, got 2 in row 0",
      "s.toml:7: key 'link[0].inner.gain': expected a number >= 0, got -1",
      "s.toml:7: key 'link[0].inner.gian': unknown key (did you mean 'gain'?)",
      "s.toml:8: key 'link[0].file': expected a string, got 3",
  };
  // `file` is given last: a required key present with the wrong type, not a missing one.
  EXPECT_EQ(errors_of("los = 0.1\ndelay = 1001\nposition = [1, 2]\nrate = \"SATURATED\"\n"
                      "values = []\nrows = [[1, 2], [4, 5]]\n"
                      "inner = { gain = -1, gian = 2 }\nfile = 3\n"),
            expected);
}

TEST(KeyCheck, RequiredKeysAndTableCounts) {
  EXPECT_EQ(errors_of("[[many]]\ngain = 1\n[[many]]\ngain = 1\n[[many]]\ngain = 1\n"),
            (std::vector<std::string>{
                "s.toml:1: key 'link[0].file': expected a string, got nothing (the key is "
                "required)",
                "s.toml:1: key 'link[0].many': expected 1..2 tables, got 3 tables"}));
  EXPECT_EQ(errors_of("file = \"x\"\n[[many]]\nname = \"a\"\n"),
            std::vector<std::string>{"s.toml:2: key 'link[0].many[0].gain': expected a number, "
                                     "got nothing (the key is required)"});
}

TEST(KeyCheck, KeysSetElsewhereAreNotMissingAndTheirErrorsSaySo) {
  KeyCheckOptions options;
  options.set_elsewhere = {"link[0].file", "link[0].delay"};
  options.note = " (swept)";
  EXPECT_EQ(errors_of("delay = -1\n", true, options),
            std::vector<std::string>{
                "s.toml:1: key 'link[0].delay': expected an integer in 0..1000, got -1 (swept)"});
}

TEST(KeyCheck, AnOpenTableKeepsItsUndeclaredKeys) {
  EXPECT_EQ(errors_of("file = \"x\"\nextension_key = 1\n", false), std::vector<std::string>{});
}

TEST(KeyCheck, FinishReportsEveryUnknownKey) {
  const toml::table doc = parse("alpha = 1\nbeta = 2\n");
  const Table t(doc, "run", "s.toml");
  t.allow("alpah");
  try {
    t.finish();
    ADD_FAILURE() << "no error";
  } catch (const ScenarioError& e) {
    EXPECT_EQ(e.messages(), (std::vector<std::string>{
                                "s.toml:1: key 'run.alpha': unknown key (did you mean 'alpah'?)",
                                "s.toml:2: key 'run.beta': unknown key (valid keys here: alpah)"}));
  }
}

TEST(KeyCheck, ScenarioErrorShowsTheFirstTwentyAndCountsTheRest) {
  std::vector<std::string> messages;
  for (int i = 0; i < 25; ++i) messages.push_back("e" + std::to_string(i));
  const ScenarioError e(messages);
  EXPECT_EQ(e.messages().size(), 25U);
  const std::string text = e.what();
  EXPECT_EQ(text.substr(0, 9), "e0\ne1\ne2\n");
  EXPECT_NE(text.find("\ne19\nand 5 more errors (25 in all; the first 20 are shown)"),
            std::string::npos)
      << text;
  EXPECT_EQ(text.find("e20"), std::string::npos);
  EXPECT_EQ(ScenarioError("one").messages(), std::vector<std::string>{"one"});
}

TEST(KeyCheck, ShapesAndWordsInTheDocs) {
  EXPECT_EQ(demo_keys().at("position").shape_text(), "3 numbers");
  EXPECT_EQ(demo_keys().at("rows").shape_text(), "rows of 3 numbers");
  EXPECT_EQ(demo_keys().at("values").shape_text(), "at least 1 value");
  EXPECT_EQ(demo_keys().at("many").shape_text(), "1..2 tables");
  EXPECT_EQ(demo_keys().at("rate").type_text(), "number or \"saturated\"");
  // The getters enforce the shapes too (the readers get them for free).
  const toml::table doc = parse("position = [1, 2, 3, 4]\n");
  const Table t(doc, "network[0]", "s.toml");
  EXPECT_EQ(error_of([&] { (void)KeyReader(t, demo_keys()).numbers("position"); }),
            "s.toml:1: key 'network[0].position': expected 3 numbers, got 4 numbers");
}

}  // namespace
}  // namespace ncosim::config
