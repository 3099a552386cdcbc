// The SQLite wrapper: statements bind by name, and a name the SQL does not
// have, or a bind SQLite refuses, is an error naming the file.
#include <gtest/gtest.h>

#include <stdexcept>
#include <string>
#include <vector>

#include "util/sqlite.hpp"

namespace vslam::sqlite {
namespace {

struct TestError : std::runtime_error {
  using std::runtime_error::runtime_error;
};
using Db = Database<TestError>;
using Stmt = Statement<TestError>;

TEST(Sqlite, NamedParametersLandInTheirColumnsWhateverTheOrderOfBinding) {
  Db db(":memory:", SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE);
  db.exec("CREATE TABLE t(a INTEGER, b REAL, c TEXT, d BLOB)");
  {
    Stmt ins(db, "INSERT INTO t (a, b, c, d) VALUES (:a, :b, :c, :d)");
    ins.bindBlob(":d", std::vector<float>{1.5f, -2.0f});
    ins.bind(":c", std::string("kitchen"));
    ins.bind(":b", 0.25);
    ins.bind(":a", int64_t{-7});
    ins.run();
  }
  Stmt sel(db, "SELECT a, b, c, d FROM t");
  ASSERT_TRUE(sel.step());
  EXPECT_EQ(sel.int64(0), -7);
  EXPECT_DOUBLE_EQ(sel.real(1), 0.25);
  EXPECT_EQ(sel.text(2), "kitchen");
  std::vector<float> d;
  ASSERT_TRUE(sel.blob(3, 2, &d));
  EXPECT_EQ(d, (std::vector<float>{1.5f, -2.0f}));
  EXPECT_FALSE(sel.blob(3, 3, &d)) << "a blob of another count is refused";
  EXPECT_FALSE(sel.step());
}

TEST(Sqlite, ANameTheStatementDoesNotHaveIsAnErrorNamingItAndTheFile) {
  Db db(":memory:", SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE);
  db.exec("CREATE TABLE t(a INTEGER)");
  Stmt ins(db, "INSERT INTO t (a) VALUES (:a)");
  try {
    ins.bind(":b", 1);
    FAIL() << "bound a parameter the SQL does not have";
  } catch (const TestError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find(":memory:"), std::string::npos) << what;
    EXPECT_NE(what.find(":b"), std::string::npos) << what;
  }
}

TEST(Sqlite, AnUnboundParameterIsNullAndRunResetsTheBindings) {
  Db db(":memory:", SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE);
  db.exec("CREATE TABLE t(a INTEGER, b TEXT)");
  Stmt ins(db, "INSERT INTO t (a, b) VALUES (:a, :b)");
  ins.bind(":a", 1);
  ins.bind(":b", std::string("x"));
  ins.run();
  ins.bind(":a", 2);  // :b not bound again: NULL, not the last row's "x"
  ins.run();
  Stmt sel(db, "SELECT b FROM t ORDER BY a");
  ASSERT_TRUE(sel.step());
  EXPECT_FALSE(sel.isNull(0));
  ASSERT_TRUE(sel.step());
  EXPECT_TRUE(sel.isNull(0));
}

TEST(Sqlite, BadSqlAndAFileThatCannotBeOpenedNameTheFile) {
  EXPECT_THROW(Db("/nonexistent-dir/x.db", SQLITE_OPEN_READWRITE), TestError);
  try {
    Db db("/nonexistent-dir/x.db", SQLITE_OPEN_READWRITE, "cannot open");
  } catch (const TestError& e) {
    EXPECT_EQ(std::string(e.what()).rfind("/nonexistent-dir/x.db: cannot open: ", 0), 0u)
        << e.what();
  }
  Db db(":memory:", SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE);
  EXPECT_THROW(Stmt(db, "SELEC nothing"), TestError);
  EXPECT_THROW(db.exec("CREATE TABLE"), TestError);
}

}  // namespace
}  // namespace vslam::sqlite
