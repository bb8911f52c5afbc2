// sim/store/store.cc — the SQLite run store (see store.h).
#include "sim/store/store.h"

#include <fmt/format.h>
#include <sqlite3.h>

#include <algorithm>
#include <bit>
#include <boost/crc.hpp>
#include <cmath>
#include <cstring>
#include <filesystem>

#include "sim/files/output_set.h"
#include "sim/store/store_sqlite.h"

namespace ncosim::sim {

namespace {

// A prepared statement, finalized on scope exit.
class Stmt {
 public:
  Stmt(sqlite3* db, const char* sql) : db_(db) {
    if (sqlite3_prepare_v2(db, sql, -1, &st_, nullptr) != SQLITE_OK) fail("prepare");
  }
  ~Stmt() { sqlite3_finalize(st_); }
  Stmt(const Stmt&) = delete;
  Stmt& operator=(const Stmt&) = delete;
  Stmt& bind(int i, std::int64_t v) {
    check(sqlite3_bind_int64(st_, i, v));
    return *this;
  }
  Stmt& bind(int i, double v) {
    check(std::isfinite(v) ? sqlite3_bind_double(st_, i, v) : sqlite3_bind_null(st_, i));
    return *this;
  }
  Stmt& bind(int i, const std::string& v) {
    check(sqlite3_bind_text(st_, i, v.data(), static_cast<int>(v.size()), SQLITE_TRANSIENT));
    return *this;
  }
  Stmt& bind_blob(int i, const std::string& v) {
    check(sqlite3_bind_blob(st_, i, v.data(), static_cast<int>(v.size()), SQLITE_TRANSIENT));
    return *this;
  }
  bool step() {
    const int rc = sqlite3_step(st_);
    if (rc == SQLITE_ROW) return true;
    if (rc == SQLITE_DONE) return false;
    fail("step");
    return false;
  }
  void reset() {
    sqlite3_reset(st_);
    sqlite3_clear_bindings(st_);
  }
  std::int64_t i64(int c) const { return sqlite3_column_int64(st_, c); }
  double f64(int c) const {
    return sqlite3_column_type(st_, c) == SQLITE_NULL ? std::nan("")
                                                      : sqlite3_column_double(st_, c);
  }
  std::string text(int c) const {
    const auto* p = reinterpret_cast<const char*>(sqlite3_column_blob(st_, c));
    return p == nullptr ? std::string()
                        : std::string(p, static_cast<std::size_t>(sqlite3_column_bytes(st_, c)));
  }

 private:
  void check(int rc) const {
    if (rc != SQLITE_OK) fail("bind");
  }
  [[noreturn]] void fail(const char* what) const {
    throw StoreError(fmt::format("run store: {}: {}", what, db_message(db_)));
  }
  sqlite3* db_;
  sqlite3_stmt* st_ = nullptr;
};

constexpr const char* kSchema = R"sql(
CREATE TABLE campaign (key TEXT PRIMARY KEY, value TEXT NOT NULL) WITHOUT ROWID;
CREATE TABLE estimators (case_index INTEGER NOT NULL, estimator INTEGER NOT NULL, name TEXT NOT NULL,
                         PRIMARY KEY (case_index, estimator)) WITHOUT ROWID;
CREATE TABLE runs (case_index INTEGER NOT NULL, run INTEGER NOT NULL, metrics BLOB NOT NULL,
                   checksum INTEGER NOT NULL, PRIMARY KEY (case_index, run)) WITHOUT ROWID;
CREATE TABLE estimator_runs (case_index INTEGER NOT NULL, run INTEGER NOT NULL, estimator INTEGER NOT NULL,
                             mse REAL, mse_ext REAL, periods INTEGER NOT NULL, samples_used INTEGER NOT NULL,
                             samples_taken INTEGER NOT NULL, diverged INTEGER NOT NULL, status TEXT NOT NULL,
                             PRIMARY KEY (case_index, run, estimator)) WITHOUT ROWID;
CREATE TABLE timing (case_index INTEGER NOT NULL, estimator INTEGER NOT NULL, ns_per_period REAL,
                     checksum INTEGER NOT NULL, PRIMARY KEY (case_index, estimator)) WITHOUT ROWID;
CREATE TABLE artifacts (name TEXT PRIMARY KEY, content BLOB NOT NULL, checksum INTEGER NOT NULL) WITHOUT ROWID;
CREATE VIEW estimator_runs_named AS
  SELECT r.case_index, r.run, e.name AS estimator, r.mse, r.mse_ext, r.periods, r.samples_used,
         r.samples_taken, r.diverged, r.status
  FROM estimator_runs r JOIN estimators e USING (case_index, estimator);
)sql";

// Per (case, run): the serialized link counters of every flow. Created with the store, and by the
// first put_runs into a store written before link counting (a --resume of one).
constexpr const char* kLinkTable =
    "CREATE TABLE IF NOT EXISTS link_runs (case_index INTEGER NOT NULL, run INTEGER NOT NULL, "
    "counters BLOB NOT NULL, checksum INTEGER NOT NULL, PRIMARY KEY (case_index, run)) WITHOUT "
    "ROWID;";

// Per case: the run-averaged error against time ([run] error_curve, sim/run/error_curve.h), summed
// over the runs it names. Created by the first add_curve (absent from stores written before it).
constexpr const char* kCurveTable =
    "CREATE TABLE IF NOT EXISTS curves (case_index INTEGER NOT NULL PRIMARY KEY, curve BLOB NOT "
    "NULL, "
    "checksum INTEGER NOT NULL);";

// CRC-32 (boost::crc_32_type) of a row: a tag naming the table, the key as 8-byte little-endian
// integers and the content. A changed byte anywhere in the row changes it.
class RowSum {
 public:
  explicit RowSum(char tag) { crc_.process_byte(static_cast<unsigned char>(tag)); }
  RowSum& key(std::int64_t v) {
    unsigned char b[8];
    for (int i = 0; i < 8; ++i)
      b[i] = static_cast<unsigned char>((static_cast<std::uint64_t>(v) >> (8 * i)) & 0xFF);
    crc_.process_bytes(b, sizeof b);
    return *this;
  }
  RowSum& bytes(const std::string& s) {
    key(static_cast<std::int64_t>(s.size()));
    crc_.process_bytes(s.data(), s.size());
    return *this;
  }
  std::int64_t value() const { return static_cast<std::int64_t>(crc_.checksum()); }

 private:
  boost::crc_32_type crc_;
};

std::int64_t run_sum(std::int64_t c, std::int64_t k, const std::string& blob) {
  return RowSum('r').key(c).key(k).bytes(blob).value();
}
std::int64_t links_sum(std::int64_t c, std::int64_t k, const std::string& blob) {
  return RowSum('l').key(c).key(k).bytes(blob).value();
}
// NaN (not measured) is stored as NULL: summed as an absent value.
std::int64_t timing_sum(std::int64_t c, std::int64_t e, double ns) {
  if (ns == 0.0) ns = 0.0;  // SQLite reads -0.0 back as +0.0
  return RowSum('t')
      .key(c)
      .key(e)
      .key(std::isfinite(ns) ? static_cast<std::int64_t>(std::bit_cast<std::uint64_t>(ns)) : -1)
      .value();
}
std::int64_t curve_sum(std::int64_t c, const std::string& blob) {
  return RowSum('c').key(c).bytes(blob).value();
}
std::int64_t artifact_sum(const std::string& name, const std::string& content) {
  return RowSum('a').bytes(name).bytes(content).value();
}

constexpr const char* kApplicationId = "ncosim run store";

}  // namespace

std::string store_path(const std::string& dir) {
  return (std::filesystem::path(dir) / "runs.sqlite").string();
}

std::string partial_store_path(const std::string& dir) {
  const std::filesystem::path folder = output_set_folder(dir);
  return (folder.parent_path() / fmt::format(".{}.partial.sqlite", folder.filename().string()))
      .string();
}

void remove_store_files(const std::string& path) {
  std::error_code ec;
  for (const char* suffix : {"", "-wal", "-shm", "-journal"})
    std::filesystem::remove(path + suffix, ec);
}

RunStore& RunStore::operator=(RunStore&& o) noexcept {
  if (this != &o) {
    if (db_ != nullptr) sqlite3_close(db_);
    db_ = o.db_;
    path_ = std::move(o.path_);
    writable_ = o.writable_;
    checksums_ = o.checksums_;
    o.db_ = nullptr;
  }
  return *this;
}

RunStore::~RunStore() {
  if (db_ != nullptr) sqlite3_close(db_);
}

void RunStore::exec(const char* sql) const {
  char* err = nullptr;
  if (sqlite3_exec(db_, sql, nullptr, nullptr, &err) != SQLITE_OK) {
    const std::string msg = db_message(db_, err);
    sqlite3_free(err);
    throw StoreError(fmt::format("run store {}: {}", path_, msg));
  }
}

RunStore RunStore::create(const std::string& path, const std::map<std::string, std::string>& meta) {
  remove_store_files(path);
  RunStore s;
  s.path_ = path;
  s.writable_ = true;
  s.checksums_ = true;
  s.db_ = open_db(path, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE);
  // WAL: readers never block the writer and a crash leaves the last committed state;
  // synchronous=FULL: a commit is on disk (power loss included) before it returns.
  s.exec("PRAGMA journal_mode=WAL; PRAGMA synchronous=FULL;");
  s.exec("BEGIN");
  s.exec(kSchema);
  s.exec(kLinkTable);
  {
    Stmt st(s.db_, "INSERT INTO campaign (key, value) VALUES (?, ?)");
    st.bind(1, std::string("store")).bind(2, std::string(kApplicationId));
    st.step();
    st.reset();
    st.bind(1, std::string("format")).bind(2, std::to_string(kFormat));
    st.step();
    for (const auto& [k, v] : meta) {
      if (k == "store" || k == "format") continue;
      st.reset();
      st.bind(1, k).bind(2, v);
      st.step();
    }
  }
  s.exec("COMMIT");
  return s;
}

namespace {

// The columns of `table` (empty when it does not exist).
std::vector<std::string> columns_of(sqlite3* db, const std::string& table) {
  std::vector<std::string> out;
  Stmt st(db, fmt::format("PRAGMA table_info({})", table).c_str());
  while (st.step()) out.push_back(st.text(1));
  return out;
}

bool has_column(sqlite3* db, const std::string& table, const std::string& column) {
  const auto cols = columns_of(db, table);
  return std::find(cols.begin(), cols.end(), column) != cols.end();
}

// What a failed open says when the user can act on it: the file is not a store, or a writer was
// killed inside a transaction and left a hot journal (SQLite's "attempt to write a readonly
// database"), which only a writer can roll back.
void refuse_unusable(const std::string& path, int code, const std::string& why) {
  if ((code & 0xFF) == SQLITE_NOTADB || why.find("no such table") != std::string::npos)
    throw StoreError(fmt::format("'{}' is not an ncosim run store", path));
  if (code == SQLITE_READONLY_ROLLBACK) {
    throw StoreError(fmt::format(
        "cannot read the run store '{}': a process writing it was killed mid-write (its "
        "-journal holds a change only a writer can undo); `ncosim run` with --resume undoes it "
        "and goes on, --replace starts afresh",
        path));
  }
}

}  // namespace

bool RunStore::holds_nothing(const std::string& path) { return store_file_holds_nothing(path); }

RunStore RunStore::open(const std::string& path, bool writable) {
  namespace fs = std::filesystem;
  std::error_code ec;
  check_store_file(path);  // sim/store/store_sqlite.h
  RunStore s;
  s.path_ = path;
  s.writable_ = writable;
  // Reading never writes: mode=ro. A store in WAL mode needs its -shm to be read, which read-only
  // media or an immutable file cannot give; a store without a -wal file is complete on its own and
  // is then read with immutable=1 (no locks, no -shm).
  auto read_marker = [&](RunStore& st) {
    Stmt m(st.db_, "SELECT value FROM campaign WHERE key = 'store'");
    return m.step() && m.text(0) == kApplicationId;
  };
  bool marker = false;
  std::string why;
  try {
    s.db_ = writable ? open_db(path, SQLITE_OPEN_READWRITE)
                     : open_db(uri_of(path, "mode=ro"), SQLITE_OPEN_READONLY | SQLITE_OPEN_URI);
    marker = read_marker(s);
  } catch (const StoreError& e) {
    why = e.what();
    const int code = s.db_ != nullptr ? sqlite3_extended_errcode(s.db_) : SQLITE_CANTOPEN;
    if (s.db_ != nullptr) sqlite3_close(s.db_);
    s.db_ = nullptr;
    refuse_unusable(path, code, why);
    // immutable=1 ignores locks and journals: only for a store that is complete on its own (no
    // -wal, no hot -journal) which could not be opened because nothing can be written beside it.
    const int primary = code & 0xFF;
    if (writable || (primary != SQLITE_CANTOPEN && primary != SQLITE_READONLY) ||
        fs::exists(path + "-wal", ec) || fs::exists(path + "-journal", ec)) {
      throw StoreError(fmt::format("cannot read the run store '{}': {}", path, why));
    }
    try {
      s.db_ = open_db(uri_of(path, "immutable=1"), SQLITE_OPEN_READONLY | SQLITE_OPEN_URI);
      marker = read_marker(s);
    } catch (const StoreError& e2) {
      const bool not_db2 = s.db_ != nullptr && sqlite3_errcode(s.db_) == SQLITE_NOTADB;
      throw StoreError(not_db2
                           ? fmt::format("'{}' is not an ncosim run store", path)
                           : fmt::format("cannot read the run store '{}': {}", path, e2.what()));
    }
  }
  if (!marker) throw StoreError(fmt::format("'{}' is not an ncosim run store", path));
  // The format: absent in stores of format 1 (before link counters were stored).
  int format = 1;
  {
    Stmt f(s.db_, "SELECT value FROM campaign WHERE key = 'format'");
    if (f.step()) {
      const std::string v = f.text(0);
      if (v != "1" && v != "2" && v != "3") {
        throw StoreError(fmt::format(
            "run store '{}': store format '{}' (this ncosim reads formats {} to {}); use "
            "the ncosim that wrote it",
            path, v.substr(0, 40), kOldestFormat, kFormat));
      }
      format = v[0] - '0';
    }
  }
  s.checksums_ = format >= 3;
  if (s.checksums_ &&
      !(has_column(s.db_, "runs", "checksum") && has_column(s.db_, "timing", "checksum") &&
        has_column(s.db_, "artifacts", "checksum"))) {
    throw StoreError(fmt::format(
        "run store '{}': format 3 without its checksum columns (the store is damaged)", path));
  }
  if (writable) {
    if (format != kFormat) {
      throw StoreError(fmt::format(
          "run store '{}' is of format {}, written by an older ncosim; it can be exported "
          "and merged, not extended (run the campaign afresh)",
          path, format));
    }
    s.exec("PRAGMA journal_mode=WAL; PRAGMA synchronous=FULL;");
  }
  return s;
}

std::map<std::string, std::string> RunStore::meta() const {
  std::map<std::string, std::string> out;
  Stmt st(db_, "SELECT key, value FROM campaign");
  while (st.step()) out[st.text(0)] = st.text(1);
  return out;
}

void RunStore::set_meta(const std::string& key, const std::string& value) {
  Stmt st(db_, "INSERT OR REPLACE INTO campaign (key, value) VALUES (?, ?)");
  st.bind(1, key).bind(2, value);
  st.step();
}

void RunStore::put_estimators(std::size_t case_index, const std::vector<std::string>& names) {
  exec("BEGIN");
  try {
    Stmt st(db_,
            "INSERT OR REPLACE INTO estimators (case_index, estimator, name) VALUES (?, ?, ?)");
    for (std::size_t e = 0; e < names.size(); ++e) {
      st.reset();
      st.bind(1, static_cast<std::int64_t>(case_index))
          .bind(2, static_cast<std::int64_t>(e))
          .bind(3, names[e]);
      st.step();
    }
  } catch (...) {
    exec("ROLLBACK");
    throw;
  }
  exec("COMMIT");
}

void RunStore::put_runs(const std::vector<StoredRun>& batch) {
  if (batch.empty()) return;
  exec("BEGIN");
  try {
    exec(kLinkTable);
    Stmt run(db_, "INSERT INTO runs (case_index, run, metrics, checksum) VALUES (?, ?, ?, ?)");
    Stmt links(db_,
               "INSERT INTO link_runs (case_index, run, counters, checksum) VALUES (?, ?, ?, ?)");
    Stmt est(db_,
             "INSERT INTO estimator_runs (case_index, run, estimator, mse, mse_ext, periods, "
             "samples_used, "
             "samples_taken, diverged, status) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?)");
    for (const StoredRun& r : batch) {
      const auto c = static_cast<std::int64_t>(r.case_index);
      const auto k = static_cast<std::int64_t>(r.run);
      run.reset();
      const std::string blob = serialize_run(r.metrics);
      run.bind(1, c).bind(2, k).bind_blob(3, blob).bind(4, run_sum(c, k, blob));
      run.step();
      if (r.links) {
        links.reset();
        const std::string lb = serialize_links(*r.links);
        links.bind(1, c).bind(2, k).bind_blob(3, lb).bind(4, links_sum(c, k, lb));
        links.step();
      }
      for (std::size_t e = 0; e < r.metrics.size(); ++e) {
        const EstimatorRunMetrics& m = r.metrics[e];
        const bool ok = !m.diverged && m.count > 0;
        const double n = static_cast<double>(m.count);
        est.reset();
        est.bind(1, c).bind(2, k).bind(3, static_cast<std::int64_t>(e));
        est.bind(4, ok ? m.sse / n : std::nan("")).bind(5, ok ? m.sse_ext / n : std::nan(""));
        est.bind(6, m.count).bind(7, m.samples_used).bind(8, m.samples_taken);
        est.bind(9, std::int64_t{m.diverged ? 1 : 0}).bind(10, m.status);
        est.step();
      }
    }
  } catch (...) {
    exec("ROLLBACK");
    throw;
  }
  exec("COMMIT");
}

std::vector<std::uint64_t> RunStore::done_runs(std::size_t case_index) const {
  std::vector<std::uint64_t> out;
  Stmt st(db_, "SELECT run FROM runs WHERE case_index = ? ORDER BY run");
  st.bind(1, static_cast<std::int64_t>(case_index));
  while (st.step()) out.push_back(static_cast<std::uint64_t>(st.i64(0)));
  return out;
}

std::int64_t RunStore::count_runs() const {
  Stmt st(db_, "SELECT count(*) FROM runs");
  st.step();
  return st.i64(0);
}

std::vector<std::pair<std::uint64_t, RunMetrics>> RunStore::load_case(
    std::size_t case_index) const {
  std::vector<std::pair<std::uint64_t, RunMetrics>> out;
  Stmt st(db_, checksums_
                   ? "SELECT run, metrics, checksum FROM runs WHERE case_index = ? ORDER BY run"
                   : "SELECT run, metrics, 0 FROM runs WHERE case_index = ? ORDER BY run");
  const auto c = static_cast<std::int64_t>(case_index);
  st.bind(1, c);
  while (st.step()) {
    const std::string blob = st.text(1);
    if (checksums_)
      check_sum(run_sum(c, st.i64(0), blob), st.i64(2),
                fmt::format("run {} of case {}", st.i64(0), c + 1));
    out.emplace_back(static_cast<std::uint64_t>(st.i64(0)), deserialize_run(blob));
  }
  return out;
}

std::vector<std::pair<std::uint64_t, RunLinks>> RunStore::load_case_links(
    std::size_t case_index) const {
  std::vector<std::pair<std::uint64_t, RunLinks>> out;
  {
    Stmt t(db_, "SELECT count(*) FROM sqlite_master WHERE type = 'table' AND name = 'link_runs'");
    t.step();
    if (t.i64(0) == 0) return out;  // a store written before link counting
  }
  Stmt st(db_,
          checksums_
              ? "SELECT run, counters, checksum FROM link_runs WHERE case_index = ? ORDER BY run"
              : "SELECT run, counters, 0 FROM link_runs WHERE case_index = ? ORDER BY run");
  const auto c = static_cast<std::int64_t>(case_index);
  st.bind(1, c);
  while (st.step()) {
    const std::string blob = st.text(1);
    if (checksums_) {
      check_sum(links_sum(c, st.i64(0), blob), st.i64(2),
                fmt::format("the link counters of run {} of case {}", st.i64(0), c + 1));
    }
    out.emplace_back(static_cast<std::uint64_t>(st.i64(0)), deserialize_links(blob));
  }
  return out;
}

void RunStore::put_timing(std::size_t case_index, const std::vector<double>& ns) {
  exec("BEGIN");
  try {
    Stmt st(db_,
            "INSERT OR REPLACE INTO timing (case_index, estimator, ns_per_period, checksum) VALUES "
            "(?, ?, ?, ?)");
    for (std::size_t e = 0; e < ns.size(); ++e) {
      st.reset();
      const auto c = static_cast<std::int64_t>(case_index);
      const auto ei = static_cast<std::int64_t>(e);
      st.bind(1, c).bind(2, ei).bind(3, ns[e]).bind(4, timing_sum(c, ei, ns[e]));
      st.step();
    }
  } catch (...) {
    exec("ROLLBACK");
    throw;
  }
  exec("COMMIT");
}

std::vector<double> RunStore::timing(std::size_t case_index, std::size_t estimators) const {
  std::vector<double> out(estimators, std::nan(""));
  Stmt st(db_, checksums_
                   ? "SELECT estimator, ns_per_period, checksum FROM timing WHERE case_index = ?"
                   : "SELECT estimator, ns_per_period, 0 FROM timing WHERE case_index = ?");
  const auto c = static_cast<std::int64_t>(case_index);
  st.bind(1, c);
  while (st.step()) {
    if (checksums_) {
      check_sum(timing_sum(c, st.i64(0), st.f64(1)), st.i64(2),
                fmt::format("the timing of estimator {} of case {}", st.i64(0) + 1, c + 1));
    }
    const auto e = static_cast<std::size_t>(st.i64(0));
    if (e < out.size()) out[e] = st.f64(1);
  }
  return out;
}

void RunStore::add_curve(std::size_t case_index, const ErrorCurve& curve) {
  if (curve.empty()) return;
  exec("BEGIN");
  try {
    exec(kCurveTable);
    ErrorCurve merged = this->curve(case_index);
    merged.merge(curve);
    const auto c = static_cast<std::int64_t>(case_index);
    const std::string blob = merged.serialize();
    Stmt st(db_, "INSERT OR REPLACE INTO curves (case_index, curve, checksum) VALUES (?, ?, ?)");
    st.bind(1, c).bind_blob(2, blob).bind(3, curve_sum(c, blob));
    st.step();
  } catch (...) {
    exec("ROLLBACK");
    throw;
  }
  exec("COMMIT");
}

ErrorCurve RunStore::curve(std::size_t case_index) const {
  Stmt exists(db_, "SELECT 1 FROM sqlite_master WHERE type = 'table' AND name = 'curves'");
  if (!exists.step()) return {};
  Stmt st(db_, "SELECT curve, checksum FROM curves WHERE case_index = ?");
  const auto c = static_cast<std::int64_t>(case_index);
  st.bind(1, c);
  if (!st.step()) return {};
  const std::string blob = st.text(0);
  check_sum(curve_sum(c, blob), st.i64(1),
            fmt::format("the error curve of case {}", case_index + 1));
  try {
    return ErrorCurve::deserialize(blob);
  } catch (const std::runtime_error& e) {
    throw StoreError(fmt::format("run store {}: the error curve of case {}: {}", path_,
                                 case_index + 1, e.what()));
  }
}

void RunStore::put_artifact(const std::string& name, const std::string& content) {
  Stmt st(db_, "INSERT OR REPLACE INTO artifacts (name, content, checksum) VALUES (?, ?, ?)");
  st.bind(1, name).bind_blob(2, content).bind(3, artifact_sum(name, content));
  st.step();
}

std::map<std::string, std::string> RunStore::artifacts() const {
  std::map<std::string, std::string> out;
  Stmt st(db_, checksums_ ? "SELECT name, content, checksum FROM artifacts"
                          : "SELECT name, content, 0 FROM artifacts");
  while (st.step()) {
    if (checksums_)
      check_sum(artifact_sum(st.text(0), st.text(1)), st.i64(2),
                fmt::format("the stored file '{}'", st.text(0)));
    out[st.text(0)] = st.text(1);
  }
  return out;
}

std::string RunStore::integrity_check() const {
  std::string out;
  Stmt st(db_, "PRAGMA integrity_check");
  while (st.step()) out += (out.empty() ? "" : "; ") + st.text(0);
  return out;
}

void RunStore::check_sum(std::int64_t computed, std::int64_t stored,
                         const std::string& what) const {
  if (computed != stored) {
    throw StoreError(
        fmt::format("run store '{}': {} fails its checksum (stored {}, computed {}): the store is "
                    "damaged; re-run the campaign, or the damaged shard",
                    path_, what, stored, computed));
  }
}

void RunStore::verify(std::size_t cases, std::uint64_t run_limit) const {
  for (const char* table : {"runs", "link_runs"}) {
    if (std::string(table) == "link_runs" && columns_of(db_, table).empty()) continue;
    Stmt st(db_, fmt::format("SELECT case_index, run, {}, {} FROM {}",
                             table == std::string("runs") ? "metrics" : "counters",
                             checksums_ ? "checksum" : "0", table)
                     .c_str());
    const bool is_runs = std::string(table) == "runs";
    while (st.step()) {
      const std::int64_t c = st.i64(0), k = st.i64(1);
      if (c < 0 || static_cast<std::uint64_t>(c) >= cases || k < 0 ||
          static_cast<std::uint64_t>(k) >= run_limit) {
        throw StoreError(fmt::format(
            "run store '{}': a stored run has case {} and run index {}, outside the campaign's "
            "{} case(s) of runs 0..{}: the store is damaged",
            path_, c + 1, k, cases, run_limit - 1));
      }
      if (checksums_) {
        const std::string blob = st.text(2);
        const std::int64_t sum = is_runs ? run_sum(c, k, blob) : links_sum(c, k, blob);
        check_sum(
            sum, st.i64(3),
            fmt::format("{}run {} of case {}", is_runs ? "" : "the link counters of ", k, c + 1));
      }
    }
  }
}

void RunStore::copy_to(const std::string& path) const {
  remove_store_files(path);
  char* sql = sqlite3_mprintf("VACUUM INTO %Q", path.c_str());
  if (sql == nullptr) throw std::bad_alloc();
  char* err = nullptr;
  const int rc = sqlite3_exec(db_, sql, nullptr, nullptr, &err);
  sqlite3_free(sql);
  if (rc != SQLITE_OK) {
    const std::string msg = db_message(db_, err);
    sqlite3_free(err);
    remove_store_files(path);
    throw StoreError(fmt::format("cannot copy the run store '{}' to '{}': {}", path_, path, msg));
  }
  // The copy is finished: one file in rollback-journal mode (readable on read-only media).
  sqlite3* db = open_db(path, SQLITE_OPEN_READWRITE);
  const int jrc = sqlite3_exec(db, "PRAGMA journal_mode=DELETE", nullptr, nullptr, nullptr);
  sqlite3_close(db);
  if (jrc != SQLITE_OK)
    throw StoreError(fmt::format("cannot finish the copy '{}' of the run store", path));
}

void RunStore::close() {
  if (db_ == nullptr) return;
  if (writable_) {
    // Finished: the WAL into the file, then back to a rollback journal so that the file alone is
    // the store (readers on read-only media need no -shm).
    sqlite3_wal_checkpoint_v2(db_, nullptr, SQLITE_CHECKPOINT_TRUNCATE, nullptr, nullptr);
    if (sqlite3_exec(db_, "PRAGMA journal_mode=DELETE", nullptr, nullptr, nullptr) != SQLITE_OK) {
      const std::string msg = db_message(db_);
      sqlite3_close(db_);
      db_ = nullptr;
      throw StoreError(fmt::format("run store {}: cannot finish it: {}", path_, msg));
    }
  }
  const int rc = sqlite3_close(db_);
  db_ = nullptr;
  if (rc != SQLITE_OK)
    throw StoreError(fmt::format("run store {}: close failed ({})", path_, sqlite3_errstr(rc)));
}

}  // namespace ncosim::sim
