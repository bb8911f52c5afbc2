// tests/config/keys_test.cc — declared keys (config/keys.h): the generic read through the
// declarations (type, default, required, range, choice), unknown keys with a did-you-mean, the
// registry entry's keys and their docs. Every expected message is written out.
#include "config/keys.h"

#include <gtest/gtest.h>

#include <stdexcept>
#include <string>

#include "config/registry.h"
#include "error_of.h"

namespace ncosim::config {
namespace {

using testing::error_of;
toml::table parse(const std::string& text) { return testing::parse_toml(text); }

const Keys& demo_keys() {
  static const Keys keys{
      Key::number("loss").probability().or_default(0.0).help("probability that a packet is lost"),
      Key::integer("delay").range(0, 1000).or_default(2).unit("periods").help("the delay"),
      Key::number("p").above(0.0).max(1.0).noun("a probability").help("success probability"),
      Key::number("gain").min(0.0).noun("a gain").optional("1 / p").help("a gain"),
      Key::boolean("on").or_default(true).help("switch"),
      Key::choice("step", {"period", "packet"}).or_default("period").help("when it moves"),
      Key::string("file").help("a file"),
      Key::numbers("pmf").probability().optional("").help("a pmf"),
      Key::matrix("A").min(-10).optional("").help("a matrix"),
  };
  return keys;
}

TEST(Keys, DefaultsLiveInTheDeclaration) {
  const toml::table doc = parse("p = 0.5\nfile = \"x.csv\"\n");
  const Table t(doc, "link[0]", "s.toml");
  const KeyReader r(t, demo_keys());
  EXPECT_EQ(r.number("loss"), 0.0);
  EXPECT_EQ(r.integer("delay"), 2);
  EXPECT_EQ(r.number("p"), 0.5);
  EXPECT_FALSE(r.opt_number("gain").has_value());
  EXPECT_TRUE(r.boolean("on"));
  EXPECT_EQ(r.string("step"), "period");
  EXPECT_EQ(r.string("file"), "x.csv");
  EXPECT_FALSE(r.has("pmf"));
  EXPECT_NO_THROW(t.finish());
}

TEST(Keys, TypeErrorsKeepTheTableMessages) {
  const toml::table doc = parse("loss = \"x\"\ndelay = 1.5\non = 1\n");
  const Table t(doc, "link[0]", "s.toml");
  const KeyReader r(t, demo_keys());
  EXPECT_EQ(error_of([&] { (void)r.number("loss"); }),
            "s.toml:1: key 'link[0].loss': expected a number, got a string \"x\"");
  EXPECT_EQ(error_of([&] { (void)r.integer("delay"); }),
            "s.toml:2: key 'link[0].delay': expected an integer, got 1.5");
  EXPECT_EQ(error_of([&] { (void)r.boolean("on"); }),
            "s.toml:3: key 'link[0].on': expected true or false, got 1");
  EXPECT_EQ(error_of([&] { (void)r.string("file"); }),
            "s.toml:1: key 'link[0].file': expected a string, got nothing (the key is required)");
  // An optional() key is required where its reader asks for it.
  EXPECT_EQ(error_of([&] { (void)r.number("gain"); }),
            "s.toml:1: key 'link[0].gain': expected a number, got nothing (the key is required)");
}

TEST(Keys, RangesAreCheckedWithOneMessage) {
  const toml::table doc = parse(
      "loss = 1.5\ndelay = 1001\np = 0\ngain = -1\npmf = [0.5, 2]\nA = [[1, -11]]\n"
      "step = \"pakcet\"\n");
  const Table t(doc, "", "s.toml");
  const KeyReader r(t, demo_keys());
  EXPECT_EQ(error_of([&] { (void)r.number("loss"); }),
            "s.toml:1: key 'loss': expected a probability in [0, 1], got 1.5");
  EXPECT_EQ(error_of([&] { (void)r.integer("delay"); }),
            "s.toml:2: key 'delay': expected an integer in 0..1000, got 1001");
  EXPECT_EQ(error_of([&] { (void)r.number("p"); }),
            "s.toml:3: key 'p': expected a probability in (0, 1], got 0");
  EXPECT_EQ(error_of([&] { (void)r.number("gain"); }),
            "s.toml:4: key 'gain': expected a gain >= 0, got -1");
  EXPECT_EQ(error_of([&] { (void)r.numbers("pmf"); }),
            "s.toml:5: key 'pmf': expected probabilities in [0, 1], got 2 at index 1");
  EXPECT_EQ(error_of([&] { (void)r.matrix("A"); }),
            "s.toml:6: key 'A': expected numbers >= -10, got -11 at [0][1]");
  EXPECT_EQ(error_of([&] { (void)r.string("step"); }),
            "s.toml:7: key 'step': expected one of \"period\", \"packet\", got \"pakcet\" (did "
            "you mean \"packet\"?)");
}

TEST(Keys, UnknownKeysAreRejectedWithADidYouMean) {
  const toml::table doc = parse("p = 0.5\nfile = \"f\"\ndelya = 3\n");
  const Table t(doc, "link[0]", "s.toml");
  const KeyReader r(t, demo_keys());
  (void)r.number("p");
  (void)r.string("file");
  (void)r.integer("delay");
  EXPECT_EQ(error_of([&] { t.finish(); }),
            "s.toml:3: key 'link[0].delya': unknown key (did you mean 'delay'?)");
}

TEST(Keys, ReadingAnUndeclaredKeyOrAnotherTypeIsABug) {
  const toml::table doc = parse("p = 0.5\n");
  const Table t(doc, "", "s.toml");
  const KeyReader r(t, demo_keys());
  EXPECT_THROW((void)r.number("nope"), std::logic_error);
  EXPECT_THROW((void)r.integer("p"), std::logic_error);
}

TEST(Keys, DeclarationsPrintAsDocs) {
  const Key& loss = demo_keys().at("loss");
  EXPECT_EQ(loss.type_text(), "number");
  EXPECT_EQ(loss.default_text(), "0.0");
  EXPECT_EQ(loss.range_text(), "[0, 1]");
  EXPECT_FALSE(loss.required());
  EXPECT_TRUE(demo_keys().at("file").required());
  EXPECT_EQ(demo_keys().at("delay").range_text(), "0..1000");
  EXPECT_EQ(demo_keys().at("gain").default_text(), "1 / p");
  const std::string md = format_keys(demo_keys(), true);
  EXPECT_NE(md.find("| `loss` | number |  | 0.0 | [0, 1] | probability that a packet is lost |"),
            std::string::npos)
      << md;
  EXPECT_NE(md.find("| `step` | choice |  | \"period\" | \"period\", \"packet\" | when it moves |"),
            std::string::npos)
      << md;
  EXPECT_NE(md.find("| `file` | string |  | required |  | a file |"), std::string::npos) << md;
}

TEST(Keys, RegistryEntriesCarryTheirKeys) {
  Registry<int> r;
  r.add("plain", "no declared keys", [](const Table&) { return 1; });
  r.add("declared", "declares its keys", demo_keys(), [](const Table& t) {
    return static_cast<int>(KeyReader(t, demo_keys()).integer("delay"));
  });
  EXPECT_TRUE(r.find("plain")->keys.empty());
  EXPECT_EQ(r.find("declared")->keys.list().size(), demo_keys().list().size());
  const toml::table doc = parse("kind = \"declared\"\n");
  const Table t(doc, "", "s.toml");
  EXPECT_EQ(r.lookup(t, "kind", "").factory(t), 2);
}

}  // namespace
}  // namespace ncosim::config
