// tests/cli/store_messages_test.cc — what the run store's refusals and failures tell a user
// (issue 40 part 7, "Messages"): SQLite's "database or disk is full" with the disk far from full
// says what it then is; --resume of another campaign names --replace (run without --resume is
// refused too); an empty store left by a campaign killed while creating it says what to do, and
// --resume starts afresh from it; after a swap interrupted between moving the previous set aside
// and renaming the new one in, report, plot, merge and export restore the previous set instead of
// "not a directory"; a damaged store's bytes never reach the terminal raw.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <random>
#include <regex>
#include <string>

#include "cli/temp_dir_test.h"
#include "sim/store/store.h"
#include "test_util.h"

namespace {

namespace fs = std::filesystem;
using ncosim::testing::read_text;
using ncosim::testing::run_shell;

const std::string kBinary = NCOSIM_BINARY;
const fs::path kBase = fs::path(NCOSIM_SOURCE_DIR) / "tests" / "cli" / "data" / "base.toml";

std::string quote(const std::string& s) { return "'" + s + "'"; }

ncosim::testing::CommandOutcome ncosim(const std::string& args, const std::string& env = "") {
  return run_shell(env + quote(kBinary) + " " + args);
}

class StoreMessages : public ncosim::testing::TempDirTest {
 protected:
  StoreMessages() : TempDirTest("ncosim_store_messages_") {}
  std::string at(const std::string& rel) const { return (dir_ / rel).string(); }
  std::string run_cmd(const std::string& out, int runs, const std::string& extra = "") const {
    return fmt::format("run {} --out {} --runs {} --periods 300 --no-timing --quiet{}",
                       quote(kBase.string()), quote(out), runs, extra);
  }
};

// Every byte of `text` printable ASCII, a newline, or part of well-formed UTF-8 (no ESC, no BEL,
// no byte of a damaged file).
bool printable(const std::string& text) {
  std::size_t i = 0;
  while (i < text.size()) {
    const auto c = static_cast<unsigned char>(text[i]);
    if (c == '\n' || (c >= 0x20 && c < 0x7F)) {
      ++i;
      continue;
    }
    const std::size_t len = c >= 0xF0 && c <= 0xF4 ? 4 : c >= 0xE0 ? 3 : c >= 0xC2 ? 2 : 0;
    if (len == 0 || c > 0xF4 || i + len > text.size()) return false;
    for (std::size_t k = 1; k < len; ++k) {
      if ((static_cast<unsigned char>(text[i + k]) & 0xC0) != 0x80) return false;
    }
    i += len;
  }
  return true;
}

// SQLite reports SQLITE_FULL when the store cannot grow (NCOSIM_TEST_MAX_PAGE_COUNT caps it, as a
// damaged store can): the message says how much the filesystem has free and what that means.
TEST_F(StoreMessages, DatabaseOrDiskIsFullWithRoomOnTheDiskSaysTheStoreIsAtFault) {
  const auto r = ncosim(run_cmd(at("out"), 40), "NCOSIM_TEST_MAX_PAGE_COUNT=3 ");
  ASSERT_NE(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("database or disk is full (SQLite's words: "), std::string::npos)
      << r.output;
  EXPECT_TRUE(std::regex_search(
      r.output,
      std::regex("GB are free beside the store, so the store is damaged or at SQLite's size "
                 "limit, not the disk; `sqlite3 '[^']*' 'PRAGMA integrity_check'` tells which")))
      << r.output;
}

// --resume of a different campaign names the option that starts afresh: run without --resume is
// refused too (the folder holds another campaign's runs).
TEST_F(StoreMessages, ResumeOfAnotherCampaignNamesReplace) {
  ASSERT_EQ(ncosim(run_cmd(at("out"), 4)).code, 0);
  auto r = ncosim(run_cmd(at("out"), 4, " --seed 9 --resume"));
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("holds a different campaign: --seed ('' vs '9') differ(s) (stored vs "
                          "now); `--replace` (without --resume) starts afresh and replaces it"),
            std::string::npos)
      << r.output;
  EXPECT_EQ(r.output.find("run without --resume to start afresh"), std::string::npos) << r.output;
  r = ncosim(run_cmd(at("out"), 4, " --seed 9 --replace"));
  EXPECT_EQ(r.code, 0) << r.output;
}

// A campaign killed while creating its store leaves an empty one beside the folder: --resume
// starts afresh from it (nothing is lost: it holds no run), and a store of 0 bytes read as a
// folder's store says what it is and what to do.
TEST_F(StoreMessages, AnEmptyStoreLeftByAKillSaysWhatToDoAndResumeStartsAfresh) {
  const std::string out = at("out");
  const std::string partial = ncosim::sim::partial_store_path(out);
  write(fs::path(partial).filename().string(), "");
  auto r = ncosim(run_cmd(out, 4, " --resume"));
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("--resume: " + partial +
                          " held no run (a campaign killed while creating its store): starting "
                          "afresh"),
            std::string::npos)
      << r.output;
  EXPECT_FALSE(fs::exists(partial));
  // An empty store beside a finished set: --resume continues the set's campaign.
  write(fs::path(partial).filename().string(), "");
  r = ncosim(run_cmd(out, 4, " --resume"));
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("(4 stored before, 0 simulated now)"), std::string::npos) << r.output;
  // A store of 0 bytes in a folder: what it is and what to do.
  fs::create_directories(at("empty"));
  write("empty/runs.sqlite", "");
  r = ncosim(fmt::format("export {} --out {}", quote(at("empty")), quote(at("e2"))));
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("is empty (0 bytes), not an ncosim run store: it holds no run (a "
                          "campaign killed while creating its store leaves one); `ncosim run` "
                          "without --resume replaces it"),
            std::string::npos)
      << r.output;
}

// A swap killed between moving the previous set aside and renaming the new one in leaves no
// folder: a reading command restores the previous set and says so (it said "not a directory").
TEST_F(StoreMessages, ReadersAfterAnInterruptedSwapRestoreThePreviousSet) {
  const std::string out = at("out");
  ASSERT_EQ(ncosim(run_cmd(out, 4)).code, 0);
  const std::string runs = read_text(out + "/runs.csv");
  const auto steps = ncosim(run_cmd(out, 4, " --seed 2 --replace"),
                            "NCOSIM_TEST_NO_EXCHANGE=1 NCOSIM_TEST_OUTPUT_STEPS=1 ");
  std::smatch m;
  ASSERT_TRUE(
      std::regex_search(steps.output, m, std::regex("output step ([0-9]+): rename the new folder")))
      << steps.output;
  const int rename_step = std::stoi(m[1]);
  for (const std::string reader : {"report {out} --no-figures", "plot {out} --format svg",
                                   "merge {m} {out}", "export {out} --out {m}"}) {
    fs::remove_all(at("m"));
    ASSERT_EQ(ncosim(run_cmd(out, 4, " --replace")).code, 0);
    const auto k =
        ncosim(run_cmd(out, 4, " --seed 3 --replace"),
               fmt::format("NCOSIM_TEST_NO_EXCHANGE=1 NCOSIM_TEST_KILL_AT={} ", rename_step));
    ASSERT_NE(k.code, 0) << k.output;
    ASSERT_FALSE(fs::exists(out)) << reader << ": the kill should leave the set moved aside";
    const auto r = ncosim(fmt::format(fmt::runtime(reader), fmt::arg("out", quote(out)),
                                      fmt::arg("m", quote(at("m")))));
    EXPECT_NE(
        r.output.find(fmt::format(
            "ncosim: restored the previous result set of '{}' (a write was interrupted)", out)),
        std::string::npos)
        << reader << ": " << r.output;
    EXPECT_EQ(r.output.find("not a directory"), std::string::npos) << reader << ": " << r.output;
    ASSERT_TRUE(fs::exists(out + "/runs.csv")) << reader;
    EXPECT_EQ(read_text(out + "/runs.csv"), runs) << reader;
  }
}

// Overwritten bytes in a store's schema or campaign fields reach the messages escaped (\xNN), never
// raw (they garbled the terminal and were invalid UTF-8).
TEST_F(StoreMessages, ADamagedStoresBytesAreEscapedInMessages) {
  ASSERT_EQ(ncosim(run_cmd(at("a"), 6)).code, 0);
  const std::string original = read_text(at("a/runs.sqlite"));
  std::mt19937_64 rng(40);
  int refused = 0;
  for (int trial = 0; trial < 60; ++trial) {
    std::string bytes = original;
    for (int i = 0; i < 16; ++i)
      bytes[rng() % bytes.size()] = static_cast<char>(0x80 | (rng() & 0x7F));
    for (int i = 0; i < 16; ++i) bytes[rng() % 4096] = static_cast<char>(rng() % 0x20);
    fs::remove_all(at("b"));
    fs::create_directories(at("b"));
    write("b/runs.sqlite", bytes);
    const auto r = ncosim(fmt::format("export {} --out {}", quote(at("b")), quote(at("c"))));
    refused += r.code == 2 ? 1 : 0;
    EXPECT_TRUE(printable(r.output)) << "trial " << trial << ": " << r.output;
  }
  EXPECT_GT(refused, 30);
}

}  // namespace
