#pragma once
// SQLite in RAII wrappers, one for every map file of the stack (the
// landmark DB's, the appearance map's). Header-only: a library that includes
// it links SQLite itself. `Error` is the caller's exception type, built from
// a message that starts with the file's name.

#include <sqlite3.h>

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

namespace vslam::sqlite {

// An open database connection.
template <class Error>
class Database {
 public:
  Database(const std::filesystem::path& file, int flags) : file_(file.string()) {
    if (sqlite3_open_v2(file_.c_str(), &db_, flags, nullptr) != SQLITE_OK) {
      const std::string why = db_ ? sqlite3_errmsg(db_) : "out of memory";
      sqlite3_close(db_);
      db_ = nullptr;
      throw Error(file_ + ": " + why);
    }
  }
  ~Database() { sqlite3_close(db_); }
  Database(const Database&) = delete;
  Database& operator=(const Database&) = delete;

  // Runs SQL that returns no rows (schema, PRAGMA, BEGIN/COMMIT).
  void exec(const std::string& sql) {
    char* err = nullptr;
    if (sqlite3_exec(db_, sql.c_str(), nullptr, nullptr, &err) != SQLITE_OK) {
      const std::string why = err ? err : sqlite3_errmsg(db_);
      sqlite3_free(err);
      throw Error(file_ + ": " + why);
    }
  }
  sqlite3* get() const { return db_; }
  const std::string& file() const { return file_; }

 private:
  std::string file_;
  sqlite3* db_ = nullptr;
};

// A prepared statement: bind by 1-based index, step through the rows, read
// columns by 0-based index.
template <class Error>
class Statement {
 public:
  Statement(sqlite3* db, const char* sql, const std::string& file) : db_(db), file_(file) {
    if (sqlite3_prepare_v2(db, sql, -1, &stmt_, nullptr) != SQLITE_OK) {
      throw Error(file_ + ": " + sqlite3_errmsg(db) + " (in: " + sql + ")");
    }
  }
  Statement(Database<Error>& db, const char* sql) : Statement(db.get(), sql, db.file()) {}
  ~Statement() { sqlite3_finalize(stmt_); }
  Statement(const Statement&) = delete;
  Statement& operator=(const Statement&) = delete;

  sqlite3_stmt* get() { return stmt_; }
  // The next row (true), or the end (false).
  bool step() {
    const int rc = sqlite3_step(stmt_);
    if (rc == SQLITE_ROW) return true;
    if (rc != SQLITE_DONE) throw Error(file_ + ": " + sqlite3_errmsg(db_));
    return false;
  }
  // Runs it once and makes it ready for new bindings.
  void run() {
    step();
    sqlite3_reset(stmt_);
    sqlite3_clear_bindings(stmt_);
  }

  void bind(int i, int64_t v) { sqlite3_bind_int64(stmt_, i, v); }
  void bind(int i, double v) { sqlite3_bind_double(stmt_, i, v); }
  void bind(int i, const std::string& v) {
    sqlite3_bind_text(stmt_, i, v.c_str(), static_cast<int>(v.size()), SQLITE_TRANSIENT);
  }
  template <class T>
  void bindBlob(int i, const std::vector<T>& v) {
    sqlite3_bind_blob(stmt_, i, v.empty() ? "" : static_cast<const void*>(v.data()),
                      static_cast<int>(v.size() * sizeof(T)), SQLITE_TRANSIENT);
  }

  int64_t int64(int c) { return sqlite3_column_int64(stmt_, c); }
  double real(int c) { return sqlite3_column_double(stmt_, c); }
  std::string text(int c) {
    const auto* t = sqlite3_column_text(stmt_, c);
    return t ? reinterpret_cast<const char*>(t) : "";
  }
  // A blob of exactly expected_count values of T; false (and *out untouched) otherwise.
  template <class T>
  bool blob(int c, size_t expected_count, std::vector<T>* out) {
    const int bytes = sqlite3_column_bytes(stmt_, c);
    if (bytes < 0 || static_cast<size_t>(bytes) != expected_count * sizeof(T)) return false;
    readBlob(c, bytes, out);
    return true;
  }
  // A blob of any whole number of values of T; false if it is not one.
  template <class T>
  bool blob(int c, std::vector<T>* out) {
    const int bytes = sqlite3_column_bytes(stmt_, c);
    if (bytes < 0 || bytes % static_cast<int>(sizeof(T)) != 0) return false;
    readBlob(c, bytes, out);
    return true;
  }

 private:
  template <class T>
  void readBlob(int c, int bytes, std::vector<T>* out) {
    out->resize(static_cast<size_t>(bytes) / sizeof(T));
    if (bytes > 0)
      std::memcpy(out->data(), sqlite3_column_blob(stmt_, c), static_cast<size_t>(bytes));
  }

  sqlite3* db_;
  std::string file_;
  sqlite3_stmt* stmt_ = nullptr;
};

}  // namespace vslam::sqlite
