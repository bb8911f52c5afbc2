// sim/store/store_sqlite.cc — SQLite helpers of the run store (see store_sqlite.h).
#include "sim/store/store_sqlite.h"

#include <fmt/format.h>
#include <sys/statvfs.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>

#include "config/config.h"
#include "sim/store/store_format.h"

namespace ncosim::sim {

// SQLite's message for the last error of `db` (or `err`), escaped: a damaged store's schema text
// can hold any byte. SQLITE_FULL ("database or disk is full") with room on the store's filesystem
// is told as what it then is: a damaged store or a size limit, not a full disk.
std::string db_message(sqlite3* db, const char* err) {
  std::string msg = config::escape_text(err != nullptr  ? err
                                        : db != nullptr ? sqlite3_errmsg(db)
                                                        : "?");
  if (db == nullptr || (sqlite3_extended_errcode(db) & 0xFF) != SQLITE_FULL) return msg;
  const char* file = sqlite3_db_filename(db, "main");
  if (file == nullptr || *file == '\0') return msg;
  const std::filesystem::path dir = std::filesystem::path(file).parent_path();
  struct statvfs fs {};
  if (::statvfs(dir.empty() ? "." : dir.c_str(), &fs) != 0) return msg;
  const double free_bytes = static_cast<double>(fs.f_bavail) * static_cast<double>(fs.f_frsize);
  std::error_code ec;
  const auto size = std::filesystem::file_size(file, ec);
  const double used = ec ? 0.0 : static_cast<double>(size);
  if (free_bytes < std::max(64e6, 2.0 * used))
    return fmt::format("{} ({:.3g} GB free beside the store)", msg, free_bytes / 1e9);
  return fmt::format(
      "{} (SQLite's words: {:.3g} GB are free beside the store, so the store is damaged or at "
      "SQLite's size limit, not the disk; `sqlite3 '{}' 'PRAGMA integrity_check'` tells which; "
      "re-running the campaign writes a new store)",
      msg, free_bytes / 1e9, file);
}

sqlite3* open_db(const std::string& path, int flags) {
  sqlite3* db = nullptr;
  const int rc = sqlite3_open_v2(path.c_str(), &db, flags, nullptr);
  if (rc != SQLITE_OK) {
    const std::string msg = db != nullptr ? db_message(db) : sqlite3_errstr(rc);
    sqlite3_close(db);
    throw StoreError(fmt::format("cannot open the run store '{}': {}", path, msg));
  }
  sqlite3_busy_timeout(db, 5000);
  sqlite3_extended_result_codes(db, 1);
  // Test hook: NCOSIM_TEST_MAX_PAGE_COUNT=N caps the store at N pages (SQLite then reports
  // SQLITE_FULL with the disk far from full, as a damaged store can).
  if (const char* pages = std::getenv("NCOSIM_TEST_MAX_PAGE_COUNT")) {
    const std::string sql = fmt::format("PRAGMA max_page_count={}", std::atol(pages));
    sqlite3_exec(db, sql.c_str(), nullptr, nullptr, nullptr);
  }
  return db;
}

// SQLite's "file:" URI of `path` with `query` (percent-encoding what a URI path cannot hold).
std::string uri_of(const std::string& path, const std::string& query) {
  std::string out = "file:";
  for (const unsigned char c : std::filesystem::absolute(path).string()) {
    if (c == '%' || c == '?' || c == '#' || c < 0x21 || c >= 0x7F) {
      out += fmt::format("%{:02X}", c);
    } else {
      out += static_cast<char>(c);
    }
  }
  return out + "?" + query;
}

void check_store_file(const std::string& path) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (!fs::exists(path, ec)) throw StoreError(fmt::format("no run store at '{}'", path));
  if (!fs::is_regular_file(path, ec))
    throw StoreError(fmt::format("'{}' is not an ncosim run store (not a regular file)", path));
  if (fs::file_size(path, ec) == 0 && !ec) {
    throw StoreError(fmt::format(
        "'{}' is empty (0 bytes), not an ncosim run store: it holds no run (a campaign killed "
        "while creating its store leaves one); `ncosim run` without --resume replaces it",
        path));
  }
}

bool store_file_holds_nothing(const std::string& path) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) return false;
  if (fs::file_size(path, ec) == 0 && !ec) return true;
  sqlite3* db = nullptr;
  if (sqlite3_open_v2(path.c_str(), &db, SQLITE_OPEN_READWRITE, nullptr) != SQLITE_OK) {
    sqlite3_close(db);
    return false;
  }
  sqlite3_busy_timeout(db, 5000);
  sqlite3_stmt* st = nullptr;
  bool empty = false;
  if (sqlite3_prepare_v2(db, "SELECT count(*) FROM sqlite_master", -1, &st, nullptr) == SQLITE_OK &&
      sqlite3_step(st) == SQLITE_ROW) {
    empty = sqlite3_column_int64(st, 0) == 0;
  }
  sqlite3_finalize(st);
  sqlite3_close(db);
  return empty;
}

}  // namespace ncosim::sim
