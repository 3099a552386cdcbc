// The map files a robot writes are readable by their owner only (mode 0600,
// util/file_mode.hpp), whatever the umask: the landmark DB's map and its
// -wal/-shm companions while it is open, and the appearance map. The umask
// here is 0, the most open one, so any file the code leaves to the default
// shows up as 0644 or 0666.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <cstdio>
#include <filesystem>
#include <string>

#include "appearance/map_file.hpp"
#include "landmark_db/landmark_store.hpp"

namespace fs = std::filesystem;
using namespace vslam;

namespace {

class MapFileModes : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string pattern = (fs::temp_directory_path() / "vslam-map-modes-XXXXXX").string();
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

}  // namespace

TEST_F(MapFileModes, TheLandmarkMapAndItsCompanionsAreOwnerOnly) {
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

TEST_F(MapFileModes, TheAppearanceMapIsOwnerOnly) {
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
