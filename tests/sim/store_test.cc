// tests/sim/store_test.cc — the run store (runs.sqlite): exact serialization, transactions,
// reading back; the campaign's run subsets, sink and stop flag; shard syntax.
#include "sim/store/store.h"

#include <gtest/gtest.h>
#include <sqlite3.h>
#include <unistd.h>

#include <bit>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>

#include "config/config.h"
#include "sim/cmd/batch.h"
#include "test_util.h"

namespace ncosim::sim {
namespace {

namespace fs = std::filesystem;
using testing::load_one;
using testing::source_path;

// A fresh folder under the system temp dir, removed at the end of the test.
struct TempDir {
  fs::path path;
  explicit TempDir(const std::string& name)
      : path(fs::temp_directory_path() /
             ("ncosim_store_" + name + "_" + std::to_string(::getpid()))) {
    fs::remove_all(path);
    fs::create_directories(path);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
};

EstimatorRunMetrics sample_metrics(int salt) {
  EstimatorRunMetrics m;
  m.sse = 0.1 + salt;
  m.sse_ext = std::nextafter(1.0, 2.0) * salt;
  m.sse_state = {1.0 / 3.0, std::numeric_limits<double>::denorm_min(), -0.0};
  m.count = 19500 + salt;
  m.samples_used = 31;
  m.samples_taken = 47;
  m.sensor_taken = {10, 20};
  m.sensor_sent = {7, 20};
  m.sensor_virtual_sse = {{0.25}, {0.5, 0.75}};
  m.diverged = salt % 2 == 1;
  m.status = salt == 2 ? "design_failed, \"quoted\"" : "ok";
  m.mode_count = 100;
  m.mode_errors = 3;
  m.confusion = {90, 3, 0, 7};
  if (salt > 0) m.counters = est::Estimator::RunCounters{1.5e9, 812.0, 20000, 4, 2};
  return m;
}

bool same_bits(double a, double b) {
  return std::bit_cast<std::uint64_t>(a) == std::bit_cast<std::uint64_t>(b);
}

void expect_identical(const EstimatorRunMetrics& a, const EstimatorRunMetrics& b) {
  EXPECT_TRUE(same_bits(a.sse, b.sse));
  EXPECT_TRUE(same_bits(a.sse_ext, b.sse_ext));
  ASSERT_EQ(a.sse_state.size(), b.sse_state.size());
  for (std::size_t i = 0; i < a.sse_state.size(); ++i)
    EXPECT_TRUE(same_bits(a.sse_state[i], b.sse_state[i]));
  EXPECT_EQ(a.count, b.count);
  EXPECT_EQ(a.samples_used, b.samples_used);
  EXPECT_EQ(a.samples_taken, b.samples_taken);
  EXPECT_EQ(a.sensor_taken, b.sensor_taken);
  EXPECT_EQ(a.sensor_sent, b.sensor_sent);
  ASSERT_EQ(a.sensor_virtual_sse.size(), b.sensor_virtual_sse.size());
  for (std::size_t s = 0; s < a.sensor_virtual_sse.size(); ++s) {
    ASSERT_EQ(a.sensor_virtual_sse[s].size(), b.sensor_virtual_sse[s].size());
    for (std::size_t i = 0; i < a.sensor_virtual_sse[s].size(); ++i) {
      EXPECT_TRUE(same_bits(a.sensor_virtual_sse[s][i], b.sensor_virtual_sse[s][i]));
    }
  }
  EXPECT_EQ(a.diverged, b.diverged);
  EXPECT_EQ(a.status, b.status);
  EXPECT_EQ(a.mode_count, b.mode_count);
  EXPECT_EQ(a.mode_errors, b.mode_errors);
  EXPECT_EQ(a.confusion, b.confusion);
  ASSERT_EQ(a.counters.has_value(), b.counters.has_value());
  if (a.counters) {
    EXPECT_TRUE(same_bits(a.counters->flops, b.counters->flops));
    EXPECT_TRUE(same_bits(a.counters->flops_worst, b.counters->flops_worst));
    EXPECT_EQ(a.counters->periods, b.counters->periods);
    EXPECT_EQ(a.counters->late, b.counters->late);
    EXPECT_EQ(a.counters->duplicates, b.counters->duplicates);
  }
}

TEST(RunStore, SerializationIsExactForEveryField) {
  RunMetrics run{sample_metrics(0), sample_metrics(1), sample_metrics(2)};
  run[1].sse = std::numeric_limits<double>::quiet_NaN();
  run[2].sse_ext = -std::numeric_limits<double>::infinity();
  const RunMetrics back = deserialize_run(serialize_run(run));
  ASSERT_EQ(back.size(), run.size());
  for (std::size_t e = 0; e < run.size(); ++e) expect_identical(run[e], back[e]);
}

TEST(RunStore, MalformedRecordsAreRejected) {
  const std::string blob = serialize_run({sample_metrics(1)});
  EXPECT_THROW(deserialize_run(blob.substr(0, blob.size() - 1)), StoreError);
  EXPECT_THROW(deserialize_run(blob + "x"), StoreError);
  std::string other = blob;
  other[0] = 9;  // format 9
  EXPECT_THROW(deserialize_run(other), StoreError);
  EXPECT_THROW(deserialize_run(""), StoreError);
}

RunLinks sample_links() {
  models::LinkCounters a;
  a.sent = 100;
  a.delivered = 91;
  a.copies = {80, 11};
  a.bursts = {5, 0, 1};
  a.states = {70, 30};
  models::LinkCounters b;  // a flow that sent nothing
  return {a, b};
}

TEST(RunStore, LinkCountersSerializationIsExactAndMalformedBlobsAreRejected) {
  const RunLinks links = sample_links();
  const std::string blob = serialize_links(links);
  const RunLinks back = deserialize_links(blob);
  ASSERT_EQ(back.size(), 2u);
  EXPECT_EQ(back[0].sent, 100);
  EXPECT_EQ(back[0].delivered, 91);
  EXPECT_EQ(back[0].copies, links[0].copies);
  EXPECT_EQ(back[0].bursts, links[0].bursts);
  EXPECT_EQ(back[0].states, links[0].states);
  EXPECT_EQ(back[1].sent, 0);
  EXPECT_TRUE(back[1].copies.empty());
  EXPECT_EQ(serialize_links(back), blob);
  EXPECT_TRUE(deserialize_links(serialize_links({})).empty());
  EXPECT_THROW(deserialize_links(blob.substr(0, blob.size() - 1)), StoreError);
  EXPECT_THROW(deserialize_links(blob + "x"), StoreError);
  std::string other = blob;
  other[0] = 9;
  EXPECT_THROW(deserialize_links(other), StoreError);
  EXPECT_THROW(deserialize_links(""), StoreError);
}

// A network node's stack counters (format 2) survive exactly, and a format 1 blob (a store written
// before them) is still read, without them.
TEST(RunStore, LinkStackCountersRoundTripAndFormatOneBlobsStillRead) {
  RunLinks links = sample_links();
  models::StackCounters& k = links[0].stack.emplace();
  k.attempts = 130;
  k.retries = 30;
  k.drops = {0, 2, 3, 4, 0};
  k.busy_ns = 123'456'789;
  k.simulated_ns = 9'000'000'000;
  const RunLinks back = deserialize_links(serialize_links(links));
  ASSERT_TRUE(back[0].stack.has_value());
  EXPECT_EQ(back[0].stack->attempts, 130);
  EXPECT_EQ(back[0].stack->retries, 30);
  EXPECT_EQ(back[0].stack->drops, k.drops);
  EXPECT_EQ(back[0].stack->busy_ns, 123'456'789);
  EXPECT_EQ(back[0].stack->simulated_ns, 9'000'000'000);
  EXPECT_FALSE(back[1].stack.has_value());
  // Format 1, little-endian 64-bit words: one flow, 7 sent, 5 delivered, copies {5}, bursts {2},
  // no states, no open run.
  std::string v1;
  for (const std::int64_t w : {1, 1, 7, 5, 1, 5, 1, 2, 0, 0}) {
    for (int i = 0; i < 8; ++i) v1.push_back(static_cast<char>((w >> (8 * i)) & 0xFF));
  }
  const RunLinks old = deserialize_links(v1);
  ASSERT_EQ(old.size(), 1u);
  EXPECT_EQ(old[0].sent, 7);
  EXPECT_EQ(old[0].delivered, 5);
  EXPECT_EQ(old[0].bursts, std::vector<std::int64_t>{2});
  EXPECT_FALSE(old[0].stack.has_value());
}

TEST(RunStore, LinkCountersAreStoredPerRunAndAStoreWithoutThemStillReads) {
  TempDir dir("links");
  const std::string path = store_path(dir.path.string());
  {
    RunStore s = RunStore::create(path, {});
    s.put_runs(
        {{0, 2, {sample_metrics(1)}, sample_links()}, {0, 0, {sample_metrics(2)}, std::nullopt}});
    s.close();
  }
  {
    const RunStore s = RunStore::open(path, false);
    const auto l = s.load_case_links(0);
    ASSERT_EQ(l.size(), 1u);  // run 0 was stored without counters
    EXPECT_EQ(l[0].first, 2u);
    EXPECT_EQ(serialize_links(l[0].second), serialize_links(sample_links()));
    EXPECT_TRUE(s.load_case_links(1).empty());
  }
  // A store written before link counting: no link_runs table at all.
  {
    sqlite3* db = nullptr;
    ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
    ASSERT_EQ(sqlite3_exec(db, "DROP TABLE link_runs", nullptr, nullptr, nullptr), SQLITE_OK);
    sqlite3_close(db);
  }
  {
    RunStore s = RunStore::open(path, true);
    EXPECT_TRUE(s.load_case_links(0).empty());
    EXPECT_EQ(s.load_case(0).size(), 2u);
    // Runs added to it (a --resume) bring the table back.
    s.put_runs({{0, 5, {sample_metrics(3)}, sample_links()}});
    const auto l = s.load_case_links(0);
    ASSERT_EQ(l.size(), 1u);
    EXPECT_EQ(l[0].first, 5u);
    EXPECT_EQ(s.integrity_check(), "ok");
  }
}

TEST(RunStore, RunsCommitInBatchesAndReadBackInRunOrder) {
  TempDir dir("batches");
  const std::string path = store_path(dir.path.string());
  {
    RunStore s = RunStore::create(path, {{"seed", "7"}, {"scenario_text", "title = \"x\"\n"}});
    s.put_estimators(0, {"kf", "s1"});
    s.put_runs({{0, 3, {sample_metrics(3), sample_metrics(4)}, std::nullopt},
                {0, 1, {sample_metrics(1), sample_metrics(2)}, std::nullopt}});
    s.put_runs({{1, 0, {sample_metrics(5), sample_metrics(6)}, std::nullopt}});
    // A duplicate (case, run) fails the whole batch: nothing of it is stored.
    EXPECT_THROW(s.put_runs({{0, 5, {sample_metrics(1)}, std::nullopt},
                             {0, 3, {sample_metrics(1)}, std::nullopt}}),
                 StoreError);
    EXPECT_EQ(s.count_runs(), 3);
    s.put_timing(0, {12.5, std::nan("")});
    s.put_artifact("trajectory.csv", "period,x1\n0,1\n");
    s.set_meta("threads", "2");
    EXPECT_EQ(s.integrity_check(), "ok");
    s.close();
  }
  EXPECT_FALSE(fs::exists(path + "-wal"));  // checkpointed on close
  const RunStore s = RunStore::open(path, false);
  EXPECT_EQ(s.meta().at("seed"), "7");
  EXPECT_EQ(s.meta().at("threads"), "2");
  EXPECT_EQ(s.done_runs(0), (std::vector<std::uint64_t>{1, 3}));
  EXPECT_EQ(s.done_runs(1), (std::vector<std::uint64_t>{0}));
  EXPECT_TRUE(s.done_runs(2).empty());
  const auto c0 = s.load_case(0);
  ASSERT_EQ(c0.size(), 2u);
  EXPECT_EQ(c0[0].first, 1u);
  expect_identical(c0[0].second[0], sample_metrics(1));
  expect_identical(c0[1].second[1], sample_metrics(4));
  const auto t = s.timing(0, 2);
  EXPECT_EQ(t[0], 12.5);
  EXPECT_TRUE(std::isnan(t[1]));
  EXPECT_TRUE(std::isnan(s.timing(1, 2)[0]));
  EXPECT_EQ(s.artifacts().at("trajectory.csv"), "period,x1\n0,1\n");
}

TEST(RunStore, CreateReplacesAndOpenRefusesWhatIsNotAStore) {
  TempDir dir("replace");
  const std::string path = store_path(dir.path.string());
  {
    RunStore s = RunStore::create(path, {});
    s.put_runs({{0, 0, {sample_metrics(1)}, std::nullopt}});
    s.close();
  }
  {
    RunStore s = RunStore::create(path, {});
    EXPECT_EQ(s.count_runs(), 0);
  }
  EXPECT_THROW(RunStore::open((dir.path / "absent.sqlite").string(), false), StoreError);
  std::ofstream((dir.path / "junk.sqlite").string()) << "not a database at all, just text\n";
  EXPECT_THROW(RunStore::open((dir.path / "junk.sqlite").string(), false), StoreError);
}

TEST(Shard, SyntaxAndOwnership) {
  const Shard s = parse_shard("2/3");
  EXPECT_EQ(s.index, 1u);
  EXPECT_EQ(s.count, 3u);
  EXPECT_TRUE(s.owns(1));
  EXPECT_TRUE(s.owns(4));
  EXPECT_FALSE(s.owns(0));
  for (const char* bad : {"", "3", "0/3", "4/3", "1/0", "a/b", "1/3x", " 1/3", "-1/3", "1//3"}) {
    EXPECT_THROW(parse_shard(bad), config::ScenarioError) << bad;
  }
}

TEST(Campaign, RunSubsetsThroughTheSinkEqualTheFullCampaign) {
  auto sc =
      load_one(source_path("scenarios/dolz2014_table2.toml"), {"run.runs=6", "run.periods=600"});
  CampaignOptions full;
  full.threads = 2;
  full.time_estimators = false;
  const CampaignResult all = run_campaign(*sc, full);
  CampaignOptions part = full;
  part.only_runs = std::vector<std::uint64_t>{1, 4, 5};
  std::map<std::uint64_t, RunMetrics> got;
  std::map<std::uint64_t, RunLinks> got_links;
  part.on_run = [&](std::uint64_t r, RunMetrics&& m, RunLinks&& l) {
    got.emplace(r, std::move(m));
    got_links.emplace(r, std::move(l));
  };
  const CampaignResult res = run_campaign(*sc, part);
  EXPECT_TRUE(res.runs.empty());  // nothing kept: the sink has them
  EXPECT_EQ(res.runs_done, 3u);
  EXPECT_FALSE(res.stopped);
  ASSERT_EQ(got.size(), 3u);
  for (const auto& [r, m] : got) {
    for (std::size_t e = 0; e < m.size(); ++e) expect_identical(m[e], all.runs[r][e]);
  }
  // The link counters too: one per flow (2 sensors behind 2 links), the same as the full
  // campaign's.
  ASSERT_EQ(all.link_runs.size(), 6u);
  for (const auto& [r, l] : got_links) {
    ASSERT_EQ(l.size(), 2u);
    EXPECT_GT(l[0].sent, 0);
    EXPECT_EQ(serialize_links(l), serialize_links(all.link_runs[r])) << "run " << r;
  }
  // Counting off: no counters, and the same metrics (counting never changes a draw).
  CampaignOptions off = full;
  off.link_counters = false;
  const CampaignResult uncounted = run_campaign(*sc, off);
  EXPECT_TRUE(uncounted.link_runs.empty());
  for (std::size_t r = 0; r < 6; ++r) {
    for (std::size_t e = 0; e < all.runs[r].size(); ++e)
      expect_identical(uncounted.runs[r][e], all.runs[r][e]);
  }
  // A stop flag already set: no run starts.
  std::atomic<int> stop{15};
  CampaignOptions stopped = full;
  stopped.stop = &stop;
  const CampaignResult none = run_campaign(*sc, stopped);
  EXPECT_EQ(none.runs_done, 0u);
  EXPECT_TRUE(none.stopped);
  EXPECT_TRUE(none.runs.empty());
}

// A writer killed inside a transaction of a store in rollback-journal mode (a finished store is
// one; the kill can also land while a store is created) leaves a hot -journal that only a writer
// can roll back: reading said SQLite's "attempt to write a readonly database". It says what
// happened and what to do; a writable open rolls the journal back and reads the store as it was.
TEST(RunStore, AHotJournalIsExplainedToAReaderAndRolledBackByAWriter) {
  TempDir dir("hot");
  const std::string path = store_path(dir.path.string());
  {
    RunStore s = RunStore::create(path, {});
    s.put_runs({{0, 0, {sample_metrics(1)}, std::nullopt}});
    s.close();  // rollback-journal mode from here
  }
  const std::string copy = path + ".copy";
  {
    sqlite3* db = nullptr;
    ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
    ASSERT_EQ(sqlite3_exec(db,
                           "PRAGMA cache_size=1; BEGIN; DELETE FROM runs; "
                           "CREATE TABLE filler(x); INSERT INTO filler VALUES (zeroblob(50000));",
                           nullptr, nullptr, nullptr),
              SQLITE_OK);
    ASSERT_TRUE(fs::exists(path + "-journal"));
    // The files as a kill now would leave them (no process holds a lock on the copy).
    fs::copy_file(path, copy);
    fs::copy_file(path + "-journal", copy + "-journal");
    sqlite3_exec(db, "ROLLBACK", nullptr, nullptr, nullptr);
    sqlite3_close(db);
  }
  try {
    (void)RunStore::open(copy, false);
    ADD_FAILURE() << "a store with a hot journal opened for reading";
  } catch (const StoreError& e) {
    EXPECT_NE(std::string(e.what()).find("a process writing it was killed mid-write (its "
                                         "-journal holds a change only a writer can undo); "
                                         "`ncosim run` with --resume undoes it"),
              std::string::npos)
        << e.what();
  }
  {
    RunStore w = RunStore::open(copy, true);
    w.close();
  }
  EXPECT_EQ(RunStore::open(copy, false).count_runs(), 1u);
}

}  // namespace
}  // namespace ncosim::sim
