// Owner-only files (util/file_mode.hpp): mode 0600 whatever the umask, an
// existing file fixed without losing its content, a clear reason when the
// system refuses, and SQLite's companion files (-journal, -wal, -shm)
// following the mode of a database file made owner-only before SQLite opens it.
#include <gtest/gtest.h>
#include <sqlite3.h>
#include <sys/stat.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include "appearance/map_file.hpp"
#include "landmark_db/landmark_store.hpp"
#include "util/file_mode.hpp"

namespace fs = std::filesystem;

namespace {

// A fresh directory, removed with what it holds.
class FileModeTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string pattern = (fs::temp_directory_path() / "vslam-file-mode-XXXXXX").string();
    ASSERT_NE(mkdtemp(pattern.data()), nullptr);
    dir_ = pattern;
    saved_umask_ = umask(0);
  }
  void TearDown() override {
    umask(saved_umask_);
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  fs::path dir_;
  mode_t saved_umask_ = 0;
};

// The permission bits of `file` in octal ("0600"), or "missing".
std::string modeOf(const fs::path& file) {
  struct stat st {};
  if (stat(file.c_str(), &st) != 0) return "missing";
  char text[8];
  std::snprintf(text, sizeof(text), "0%03o", static_cast<unsigned>(st.st_mode & 07777));
  return text;
}

std::string contentOf(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void exec(sqlite3* db, const char* sql) {
  char* err = nullptr;
  const int rc = sqlite3_exec(db, sql, nullptr, nullptr, &err);
  const std::string why = err ? err : "";
  sqlite3_free(err);
  ASSERT_EQ(rc, SQLITE_OK) << sql << ": " << why;
}

}  // namespace

TEST_F(FileModeTest, ANewFileIsOwnerOnlyWhateverTheUmask) {
  // 0: open() alone would give what it asks; 0277: it would give 0400, which
  // the owner could not write; 0022, the usual one: 0644 for everyone to read.
  for (const mode_t mask : {0000, 0277, 0022}) {
    umask(mask);
    const fs::path file = dir_ / ("map-" + std::to_string(mask) + ".db");
    const auto why = vslam::util::createOwnerOnly(file);
    ASSERT_FALSE(why) << *why;
    EXPECT_EQ(modeOf(file), "0600") << "umask 0" << std::oct << mask;
    EXPECT_EQ(fs::file_size(file), 0u);
  }
}

TEST_F(FileModeTest, AnExistingFileIsRestrictedAndKeepsItsContent) {
  const fs::path file = dir_ / "old-map.db";
  std::ofstream(file) << "stored landmarks";
  fs::permissions(file, fs::perms(0644));
  ASSERT_EQ(modeOf(file), "0644");
  ASSERT_FALSE(vslam::util::createOwnerOnly(file));
  EXPECT_EQ(modeOf(file), "0600");
  EXPECT_EQ(contentOf(file), "stored landmarks") << "never truncated";

  // Read-only for everyone: still fixed (opened for reading only).
  fs::permissions(file, fs::perms(0444));
  ASSERT_FALSE(vslam::util::createOwnerOnly(file));
  EXPECT_EQ(modeOf(file), "0600");

  fs::permissions(file, fs::perms(0664));
  ASSERT_FALSE(vslam::util::restrictToOwner(file));
  EXPECT_EQ(modeOf(file), "0600");
  EXPECT_EQ(contentOf(file), "stored landmarks");
}

TEST_F(FileModeTest, AFailureSaysWhatFailedAndWhy) {
  const auto no_dir = vslam::util::createOwnerOnly(dir_ / "no-such-dir" / "map.db");
  ASSERT_TRUE(no_dir);
  EXPECT_EQ(*no_dir,
            "cannot create or open (to make it owner-only, mode 0600): No such file or directory");
  const auto missing = vslam::util::restrictToOwner(dir_ / "missing.db");
  ASSERT_TRUE(missing);
  EXPECT_EQ(*missing,
            "cannot change its mode (to make it owner-only, mode 0600): No such file or directory");
  const auto directory = vslam::util::createOwnerOnly(dir_);
  ASSERT_TRUE(directory);
  EXPECT_NE(directory->find("Is a directory"), std::string::npos) << *directory;
}

TEST_F(FileModeTest, SqliteCompanionFilesFollowAnOwnerOnlyDatabase) {
  umask(0022);
  const fs::path file = dir_ / "map.db";
  ASSERT_FALSE(vslam::util::createOwnerOnly(file));
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open_v2(file.c_str(), &db, SQLITE_OPEN_READWRITE, nullptr), SQLITE_OK)
      << "SQLite takes the empty file as a new database";
  // A rollback journal kept after the commit (PERSIST), then WAL and its
  // shared memory, each created by SQLite beside the database.
  exec(db, "PRAGMA journal_mode=PERSIST; CREATE TABLE t(x); INSERT INTO t VALUES (1);");
  EXPECT_EQ(modeOf(dir_ / "map.db-journal"), "0600");
  exec(db, "PRAGMA journal_mode=WAL; INSERT INTO t VALUES (2);");
  EXPECT_EQ(modeOf(dir_ / "map.db-wal"), "0600");
  EXPECT_EQ(modeOf(dir_ / "map.db-shm"), "0600");
  EXPECT_EQ(modeOf(file), "0600");
  sqlite3_close(db);

  // Without it, the same steps give files everyone can read.
  const fs::path plain = dir_ / "plain.db";
  ASSERT_EQ(
      sqlite3_open_v2(plain.c_str(), &db, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE, nullptr),
      SQLITE_OK);
  exec(db, "PRAGMA journal_mode=WAL; CREATE TABLE t(x); INSERT INTO t VALUES (1);");
  EXPECT_EQ(modeOf(plain), "0644");
  EXPECT_EQ(modeOf(dir_ / "plain.db-wal"), "0644");
  sqlite3_close(db);
}

// The map files a robot writes, through their own code. The umask here is 0,
// the most open one, so any file the code leaves to the default shows up as
// 0644 or 0666.
namespace {

namespace landmark_db = vslam::landmark_db;
namespace appearance = vslam::appearance;

landmark_db::LandmarkStructure onePointStructure() {
  landmark_db::LandmarkStructure s;
  s.num_points = 1;
  s.descriptor_size = 128;
  s.points = {2.0f, 0.0f, 0.5f};
  s.keypoints = {0.1f, 0.2f};
  s.scales = {2.0f};
  s.orientations = {0.3f};
  s.descriptors.assign(128, 7);
  return s;
}

TEST_F(FileModeTest, TheLandmarkMapAndItsCompanionsAreOwnerOnly) {
  const fs::path file = dir_ / "maps" / "landmarks.db";
  {
    landmark_db::StoreOptions options;
    options.new_database_id = "modes-test";
    landmark_db::LandmarkStore store(file, options);
    landmark_db::LandmarkInfo info;
    info.camera = "forward";
    info.proposal_id = 1;
    store.insert(info, onePointStructure(), 1);
    // Open, in WAL mode, after a write: all three files are there.
    EXPECT_EQ(modeOf(file), "0600") << file;
    EXPECT_EQ(modeOf(file.string() + "-wal"), "0600")
        << "the WAL holds the landmarks until a checkpoint";
    EXPECT_EQ(modeOf(file.string() + "-shm"), "0600");
  }
  EXPECT_EQ(modeOf(file), "0600") << "after closing";
  // Opened again (the path an existing map takes).
  {
    landmark_db::LandmarkStore store(file, landmark_db::StoreOptions{});
    EXPECT_EQ(store.loadAllInfo().size(), 1u);
    EXPECT_EQ(modeOf(file.string() + "-wal"), "0600");
    EXPECT_EQ(modeOf(file.string() + "-shm"), "0600");
  }
}

TEST_F(FileModeTest, TheAppearanceMapIsOwnerOnly) {
  appearance::SavedMap map;
  map.cameras = {"forward"};
  map.bins = 4;
  appearance::State state;
  state.id = 0;
  state.histograms = {{0.25f, 0.25f, 0.25f, 0.25f}};
  map.states.push_back(state);
  map.path.push_back({0, appearance::Link{}});
  const fs::path file = dir_ / "appearance.db";
  appearance::saveMap(file, map);
  EXPECT_EQ(modeOf(file), "0600");
  EXPECT_EQ(modeOf(file.string() + ".tmp"), "missing") << "renamed, not left beside it";
  // Saved again over an existing map (the process saves as it goes).
  appearance::saveMap(file, map);
  EXPECT_EQ(modeOf(file), "0600");
  EXPECT_EQ(appearance::loadMap(file).states.size(), 1u);
}

}  // namespace
