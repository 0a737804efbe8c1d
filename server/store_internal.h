// Private to the JobStore's source files (store*.cpp): its prepared
// statement and the encoding of Stats shared by writes and reads. Not part
// of the coordinator's interface.
#pragma once

#include <sqlite3.h>

#include <cstdint>
#include <string>
#include <string_view>

#include "server/store.h"

namespace locus::farm {

// A prepared statement, finalized on scope exit. Binding is by position
// (1-based) through bind(); step() returns SQLITE_ROW / SQLITE_DONE.
// Statements are prepared once per store and kept (keyed by their SQL).
// Bytes bound as a BLOB (pixels), not as text.
struct Blob {
  std::string_view bytes;
};

class JobStore::Statement {
 public:
  Statement(JobStore& store, const char* sql) : db_(store.db_) {
    auto it = store.cache_.find(sql);
    if (it != store.cache_.end()) {
      stmt_ = it->second;
      return;
    }
    rc_ = sqlite3_prepare_v2(db_, sql, -1, &stmt_, nullptr);
    if (rc_ == SQLITE_OK) store.cache_.emplace(sql, stmt_);
  }
  ~Statement() {
    sqlite3_reset(stmt_);
    sqlite3_clear_bindings(stmt_);
  }
  Statement(const Statement&) = delete;
  Statement& operator=(const Statement&) = delete;

  template <typename... Args>
  Statement& bind(const Args&... args) {
    int i = 0;
    (bind_one(++i, args), ...);
    return *this;
  }
  int step() {
    if (rc_ != SQLITE_OK) return rc_;
    return sqlite3_step(stmt_);
  }
  // Runs a statement that returns no rows.
  Status run() {
    const int rc = step();
    if (rc != SQLITE_DONE && rc != SQLITE_ROW) return error();
    return Status::Ok();
  }
  Status error() const { return Internal(std::string("job store: ") + sqlite3_errmsg(db_)); }
  int64_t integer(int col) const { return sqlite3_column_int64(stmt_, col); }
  double real(int col) const { return sqlite3_column_double(stmt_, col); }
  bool null(int col) const { return sqlite3_column_type(stmt_, col) == SQLITE_NULL; }
  std::string text(int col) const {
    const auto* p = static_cast<const char*>(sqlite3_column_blob(stmt_, col));
    return p ? std::string(p, sqlite3_column_bytes(stmt_, col)) : std::string();
  }

 private:
  void bind_one(int i, int64_t v) { sqlite3_bind_int64(stmt_, i, v); }
  void bind_one(int i, int v) { sqlite3_bind_int64(stmt_, i, v); }
  void bind_one(int i, bool v) { sqlite3_bind_int64(stmt_, i, v ? 1 : 0); }
  void bind_one(int i, double v) { sqlite3_bind_double(stmt_, i, v); }
  void bind_one(int i, const std::string& v) {
    sqlite3_bind_text(stmt_, i, v.data(), static_cast<int>(v.size()), SQLITE_TRANSIENT);
  }
  void bind_one(int i, const char* v) { sqlite3_bind_text(stmt_, i, v, -1, SQLITE_TRANSIENT); }
  void bind_one(int i, std::nullptr_t) { sqlite3_bind_null(stmt_, i); }
  void bind_one(int i, const Blob& v) {
    sqlite3_bind_blob64(stmt_, i, v.bytes.data(), v.bytes.size(), SQLITE_STATIC);
  }

  sqlite3* db_;
  sqlite3_stmt* stmt_ = nullptr;
  int rc_ = SQLITE_OK;
};

namespace store_detail {

// A job's or band's Stats as the store's text keeps them (encode_stats in
// store.cpp writes them).
Stats decode_stats(const std::string& text);

}  // namespace store_detail
}  // namespace locus::farm
