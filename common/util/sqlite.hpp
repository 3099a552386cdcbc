#pragma once
// SQLite in RAII wrappers, one for every map file of the stack (the
// landmark DB's, the appearance map's). Header-only: a library that includes
// it links SQLite itself. `Error` is the caller's exception type, built from
// a message that starts with the file's name.
//
// Statements bind by name (":camera"), never by position: a statement of 25
// columns bound by number breaks silently when a column moves; a name that
// the SQL does not have is an error here.

#include <sqlite3.h>

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <string>
#include <type_traits>
#include <vector>

namespace vslam::sqlite {

// An open database connection.
template <class Error>
class Database {
 public:
  // A failure to open throws "<file>: <what>: <SQLite's reason>".
  Database(const std::filesystem::path& file, int flags, const std::string& what = "cannot open")
      : file_(file.string()) {
    if (sqlite3_open_v2(file_.c_str(), &db_, flags, nullptr) != SQLITE_OK) {
      const std::string why = db_ ? sqlite3_errmsg(db_) : "out of memory";
      sqlite3_close(db_);
      db_ = nullptr;
      throw Error(file_ + ": " + what + ": " + why);
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
  // Like exec, for the clean-up of a destructor: never throws.
  bool tryExec(const char* sql) noexcept {
    return sqlite3_exec(db_, sql, nullptr, nullptr, nullptr) == SQLITE_OK;
  }
  const char* lastError() const { return sqlite3_errmsg(db_); }
  sqlite3* get() const { return db_; }
  const std::string& file() const { return file_; }

 private:
  std::string file_;
  sqlite3* db_ = nullptr;
};

// A prepared statement: bind by parameter name, step through the rows, read
// columns by 0-based index (in the order the SELECT names them).
template <class Error>
class Statement {
 public:
  Statement(Database<Error>& db, const char* sql) : db_(db.get()), file_(db.file()) {
    if (sqlite3_prepare_v2(db_, sql, -1, &stmt_, nullptr) != SQLITE_OK) {
      throw Error(file_ + ": " + sqlite3_errmsg(db_) + " (in: " + sql + ")");
    }
  }
  ~Statement() { sqlite3_finalize(stmt_); }
  Statement(const Statement&) = delete;
  Statement& operator=(const Statement&) = delete;

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

  template <class T, std::enable_if_t<std::is_integral_v<T>, int> = 0>
  void bind(const char* name, T v) {
    check(sqlite3_bind_int64(stmt_, index(name), static_cast<sqlite3_int64>(v)), name);
  }
  void bind(const char* name, double v) { check(sqlite3_bind_double(stmt_, index(name), v), name); }
  void bind(const char* name, const std::string& v) {
    check(sqlite3_bind_text(stmt_, index(name), v.c_str(), static_cast<int>(v.size()),
                            SQLITE_TRANSIENT),
          name);
  }
  // The values' bytes as a blob (little-endian on the machines we run on).
  template <class T>
  void bindBlob(const char* name, const std::vector<T>& v) {
    static_assert(std::is_trivially_copyable_v<T>);
    check(sqlite3_bind_blob(stmt_, index(name), v.empty() ? "" : static_cast<const void*>(v.data()),
                            static_cast<int>(v.size() * sizeof(T)), SQLITE_TRANSIENT),
          name);
  }

  int64_t int64(int c) { return sqlite3_column_int64(stmt_, c); }
  double real(int c) { return sqlite3_column_double(stmt_, c); }
  // NULL reads as "".
  std::string text(int c) {
    const auto* t = sqlite3_column_text(stmt_, c);
    return t ? reinterpret_cast<const char*>(t) : "";
  }
  bool isNull(int c) { return sqlite3_column_type(stmt_, c) == SQLITE_NULL; }
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
  int index(const char* name) {
    const int i = sqlite3_bind_parameter_index(stmt_, name);
    if (i == 0) {
      throw Error(file_ + ": the statement has no parameter " + name +
                  " (in: " + sqlite3_sql(stmt_) + ")");
    }
    return i;
  }
  void check(int rc, const char* name) {
    if (rc != SQLITE_OK) {
      throw Error(file_ + ": cannot bind " + name + ": " + sqlite3_errstr(rc));
    }
  }
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
