// Counting the rows of a table in a session database (SQLite) from tests,
// without writing to it: a runner may hold it open in another process.
#pragma once

#include <sqlite3.h>

#include <filesystem>
#include <string>

namespace avsi::test {

// Rows of `table` in the database `db` so far; 0 before the database or the
// table exists. Waits up to 2 s for a writer's lock.
inline int count_rows(const std::filesystem::path& db, const std::string& table) {
    if (!std::filesystem::exists(db)) return 0;
    sqlite3* handle = nullptr;
    int n = 0;
    if (sqlite3_open_v2(db.c_str(), &handle, SQLITE_OPEN_READONLY, nullptr) == SQLITE_OK) {
        sqlite3_busy_timeout(handle, 2000);
        sqlite3_stmt* st = nullptr;
        if (sqlite3_prepare_v2(handle, ("SELECT count(*) FROM " + table).c_str(), -1, &st, nullptr) == SQLITE_OK &&
            sqlite3_step(st) == SQLITE_ROW)
            n = sqlite3_column_int(st, 0);
        sqlite3_finalize(st);
    }
    sqlite3_close(handle);
    return n;
}

}  // namespace avsi::test
