// sim/store/store_sqlite.h — SQLite helpers of the run store (sim/store/store.cc): opening a
// database, SQLite's messages made safe to print, a file URI.
#pragma once

#include <sqlite3.h>

#include <string>

namespace ncosim::sim {

// SQLite's message for the last error of `db` (or `err`), escaped: a damaged store's schema text
// can hold any byte. SQLITE_FULL ("database or disk is full") with room on the store's filesystem
// is told as what it then is: a damaged store or a size limit, not a full disk.
std::string db_message(sqlite3* db, const char* err = nullptr);

// sqlite3_open_v2 with the store's settings (busy timeout, extended codes); throws StoreError.
// Test hook: NCOSIM_TEST_MAX_PAGE_COUNT=N caps every store at N pages.
sqlite3* open_db(const std::string& path, int flags);

// Throws StoreError when `path` is missing, not a regular file or empty (0 bytes: what a campaign
// killed while creating its store leaves), saying what it is and what to do.
void check_store_file(const std::string& path);

// Whether `path` is a store that holds nothing: 0 bytes, or an SQLite file without a table (what
// a campaign killed while creating its store leaves). RunStore::holds_nothing.
bool store_file_holds_nothing(const std::string& path);

// SQLite's "file:" URI of `path` with `query` (percent-encoding what a URI path cannot hold).
std::string uri_of(const std::string& path, const std::string& query);

}  // namespace ncosim::sim
