// sim/store/store.h — the run store: runs.sqlite in the output folder. Every completed run of a
// campaign is committed to it as it finishes (SQLite, WAL journal, one transaction per batch
// of runs), with everything needed to re-derive every export bit-identically: per (case, run)
// a complete binary serialization of every estimator's per-run metrics, readable scalar
// columns per (case, run, estimator), the estimators' measured time per period, and a
// campaign table (scenario text, hash, commit, seed and the options that define the
// campaign's identity). Schema: results/README.md, "runs.sqlite".
//
// Integrity (format 3): every row that an export is derived from (runs, link_runs, timing,
// artifacts) carries a CRC-32 of its key and content, verified whenever the row is read; a damaged
// row is a StoreError naming it, never a silently changed result. A store is finished by close():
// WAL checkpointed and the journal mode set back to DELETE, so that a finished store is one file
// that can be read on read-only media without creating -wal or -shm files. Reading never writes.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "sim/run/campaign.h"
#include "sim/store/store_format.h"

struct sqlite3;

namespace ncosim::sim {

// One completed run, ready to commit.
struct StoredRun {
  std::size_t case_index = 0;
  std::uint64_t run = 0;
  RunMetrics metrics;
  std::optional<RunLinks> links;  // nullopt: not counted (no row in link_runs)
};

class RunStore {
 public:
  RunStore() = default;
  RunStore(const RunStore&) = delete;
  RunStore& operator=(const RunStore&) = delete;
  RunStore(RunStore&& o) noexcept
      : db_(o.db_), path_(std::move(o.path_)), writable_(o.writable_), checksums_(o.checksums_) {
    o.db_ = nullptr;
  }
  RunStore& operator=(RunStore&& o) noexcept;
  ~RunStore();

  // A new, empty store at `path` (an existing file and its -wal/-shm are removed first),
  // with the campaign table filled from `meta`. Throws StoreError.
  static RunStore create(const std::string& path, const std::map<std::string, std::string>& meta);
  // An existing store. Throws StoreError when it is missing, not a run store, of a format this
  // ncosim does not read, or (writable) of an older format than it writes. A read-only open
  // never writes: on read-only media or an immutable file it reads the finished store as is.
  static RunStore open(const std::string& path, bool writable);

  // Whether the file at `path` holds nothing a store could: 0 bytes, or an SQLite database without
  // a single table (a campaign killed while it created its store). Opens it writable (an
  // interrupted transaction is rolled back): only for a store about to be replaced or resumed.
  static bool holds_nothing(const std::string& path);

  // The format this ncosim writes ("3": checksummed rows) and the oldest it reads.
  static constexpr int kFormat = 3;
  static constexpr int kOldestFormat = 1;

  // Verifies every stored run: case index below `cases`, run index below `run_limit`, and the
  // checksums of its rows. Throws StoreError naming the first bad run.
  void verify(std::size_t cases, std::uint64_t run_limit) const;

  // A consistent, finished copy of this store at `path` (which must not exist), for a result set
  // elsewhere; works on a read-only store.
  void copy_to(const std::string& path) const;

  const std::string& path() const { return path_; }
  bool is_open() const { return db_ != nullptr; }

  std::map<std::string, std::string> meta() const;
  void set_meta(const std::string& key, const std::string& value);

  // Estimator names of a case (readable columns), set once per case.
  void put_estimators(std::size_t case_index, const std::vector<std::string>& names);
  // Commits the batch in one transaction. A (case, run) already stored is an error.
  void put_runs(const std::vector<StoredRun>& batch);
  // Run indices stored for a case, ascending.
  std::vector<std::uint64_t> done_runs(std::size_t case_index) const;
  std::int64_t count_runs() const;
  // Every stored run of a case in run order.
  std::vector<std::pair<std::uint64_t, RunMetrics>> load_case(std::size_t case_index) const;
  // The stored link counters of a case's runs, in run order (runs without counters, e.g. of a
  // store written before link counting, are absent; so is everything when the store has no
  // link_runs table).
  std::vector<std::pair<std::uint64_t, RunLinks>> load_case_links(std::size_t case_index) const;
  // Measured ns per period per estimator (NaN: not measured); empty when never stored.
  void put_timing(std::size_t case_index, const std::vector<double>& ns);
  std::vector<double> timing(std::size_t case_index, std::size_t estimators) const;
  // The run-averaged error curve of a case ([run] error_curve): `curve` is added to the stored one
  // in one transaction (its runs must not be in it yet). curve() is empty when none is stored.
  void add_curve(std::size_t case_index, const ErrorCurve& curve);
  ErrorCurve curve(std::size_t case_index) const;
  // Named text artefacts (e.g. trajectory.csv of a --trace run).
  void put_artifact(const std::string& name, const std::string& content);
  std::map<std::string, std::string> artifacts() const;

  // "ok" or SQLite's integrity_check report.
  std::string integrity_check() const;
  // Checkpoints the WAL into the database file and closes (the -wal file is removed).
  void close();

 private:
  void exec(const char* sql) const;
  // Throws StoreError naming `what` when a row's checksum differs from the stored one.
  void check_sum(std::int64_t computed, std::int64_t stored, const std::string& what) const;
  sqlite3* db_ = nullptr;
  std::string path_;
  bool writable_ = false;
  bool checksums_ = false;  // rows carry checksums (format 3)
};

// The store of an output folder's result set.
std::string store_path(const std::string& dir);
// Where a campaign writing into `dir` builds its store until its result set is swapped in:
// PARENT/.NAME.partial.sqlite beside the folder (NAME once symlinks are resolved). A killed
// campaign leaves it there for `--resume`; the folder keeps its previous, consistent set.
std::string partial_store_path(const std::string& dir);
// Removes the store at `path` with its -wal, -shm and -journal files.
void remove_store_files(const std::string& path);

}  // namespace ncosim::sim
