// World files: loading, every kind of error naming file + line + key, and the
// floor-plan queries the simulator plans with.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>

#include "config/config_node.hpp"
#include "world/geometry2d.hpp"
#include "world/world.hpp"

namespace fs = std::filesystem;
using vslam::config::ConfigError;
using namespace vslam::world;

namespace {

const fs::path kSource = VSLAM_SOURCE_DIR;
const fs::path kWorlds = kSource / "config/worlds";

// A 4 x 3 m room and a 2 x 3 m room east of it, a door between them, a
// table (1.0 wide along x, 0.6 deep along y: it faces +y).
const char* kTwoRooms = R"(materials:
  paint: {albedo: 0.7}
  brick: {texture: "skimage:brick.png", scale_m: 1.2, rotate_deg: 90}
rooms:
  - name: west
    polygon: [[0, 0], [4, 0], [4, 3], [0, 3]]
    height: 2.5
    walls: brick
    floor: paint
    ceiling: paint
  - name: east
    polygon: [[4, 0], [6, 0], [6, 3], [4, 3]]
    height: 2.5
    walls: paint
    floor: paint
    ceiling: paint
doors:
  - {at: [4, 1.5], width: 0.9}
boxes:
  - {name: table, centre: [1.0, 1.0], size: [1.0, 0.6, 0.7], facing_deg: 90, material: paint}
)";

fs::path scratchDir() {
  const fs::path d =
      fs::temp_directory_path() / ("vslam_test_world_" + std::to_string(::getpid()) + "_" +
                                   ::testing::UnitTest::GetInstance()->current_test_info()->name());
  fs::create_directories(d);
  return d;
}

// Expects loading `text` as `name` to throw a ConfigError that names the
// file, the key and the line.
void expectLoadError(const std::string& text, const std::string& key, int line,
                     const std::string& problem_part) {
  const fs::path dir = scratchDir();
  const fs::path file = dir / "bad_world.yaml";
  std::ofstream(file) << text;
  try {
    World::loadFile(file);
    ADD_FAILURE() << "no error for key '" << key << "' in:\n" << text;
  } catch (const ConfigError& e) {
    const std::string what = e.what();
    EXPECT_EQ(e.file(), file.string()) << what;
    EXPECT_EQ(e.key(), key) << what;
    EXPECT_NE(what.find(file.string()), std::string::npos) << what;
    EXPECT_NE(what.find("line " + std::to_string(line) + ":"), std::string::npos) << what;
    EXPECT_NE(what.find(problem_part), std::string::npos) << what;
  }
  fs::remove_all(dir);
}

std::string replaced(std::string s, const std::string& from, const std::string& to) {
  const size_t at = s.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  return s.replace(at, from.size(), to);
}

}  // namespace

TEST(WorldFile, TwoRoomsLoad) {
  const World w = World::loadString(kTwoRooms, "two_rooms.yaml");
  ASSERT_EQ(w.rooms.size(), 2u);
  EXPECT_EQ(w.rooms[0].name, "west");
  EXPECT_EQ(w.textures.size(), 1u);  // the brick, rotated once
  EXPECT_EQ(w.doors.size(), 1u);
  EXPECT_EQ(w.obstacles.size(), 1u);
  // Door on the shared wall: both rooms' walls are cut (2 solid runs each
  // side) plus the outside walls: west 3 + 2, east 3 + 2.
  EXPECT_EQ(w.walls.size(), 10u);
  EXPECT_EQ(w.file, "two_rooms.yaml");
  // Every surface belongs to a room and faces into it: its normal points at
  // the room side (checked with the centre nudged along the normal).
  for (const Surface& s : w.surfaces) {
    Eigen::Vector3d n = Eigen::Vector3d::Zero(), c = Eigen::Vector3d::Zero();
    for (int i = 0; i < 4; ++i)
      n += s.corners[i].cross(s.corners[(i + 1) % 4]), c += s.corners[i] / 4;
    ASSERT_GT(n.norm(), 0.0);
    ASSERT_GE(s.room, 0);
    const Eigen::Vector3d probe = c + 0.05 * n.normalized();
    EXPECT_GT(probe.z(), 0.0);
    EXPECT_LT(probe.z(), 2.5);
    const bool in_box =
        std::abs(probe.x() - 1.0) <= 0.55 && std::abs(probe.y() - 1.0) <= 0.35 && probe.z() <= 0.75;
    if (!in_box) {
      EXPECT_EQ(w.roomIndexAt(probe.x(), probe.y()), s.room) << c.transpose();
    }
  }
}

TEST(WorldFile, IsFreeAndRoomAt) {
  const World w = World::loadString(kTwoRooms, "two_rooms.yaml");
  EXPECT_TRUE(w.isFree(2.5, 2.0, 0.15));  // west room, open floor
  EXPECT_TRUE(w.isFree(5.0, 1.5, 0.15));  // east room centre
  EXPECT_EQ(w.roomAt(2.5, 2.0), "west");
  EXPECT_EQ(w.roomAt(5.0, 1.5), "east");
  EXPECT_EQ(w.roomAt(7.0, 1.5), "");
  EXPECT_EQ(w.roomIndexAt(5.0, 1.5), 1);
  EXPECT_FALSE(w.isFree(4.0, 0.5, 0.15));   // on the shared wall, beside the door
  EXPECT_FALSE(w.isFree(3.9, 0.5, 0.15));   // disc overlaps that wall
  EXPECT_TRUE(w.isFree(3.8, 0.5, 0.15));    // just clear of it
  EXPECT_TRUE(w.isFree(4.0, 1.5, 0.15));    // in the door gap (0.9 m wide)
  EXPECT_FALSE(w.isFree(4.0, 1.5, 0.5));    // too wide for the door
  EXPECT_FALSE(w.isFree(1.0, 1.0, 0.15));   // inside the table
  EXPECT_FALSE(w.isFree(1.0, 1.45, 0.15));  // table edge at y = 1.3 within the radius
  EXPECT_TRUE(w.isFree(1.0, 1.5, 0.15));
  EXPECT_FALSE(w.isFree(-1.0, 1.0, 0.15));  // outside every room
  EXPECT_FALSE(w.isFree(0.1, 1.0, 0.15));   // against the outside wall
  const Eigen::AlignedBox2d b = w.bounds();
  EXPECT_DOUBLE_EQ(b.min().x(), 0.0);
  EXPECT_DOUBLE_EQ(b.max().x(), 6.0);
  EXPECT_DOUBLE_EQ(b.max().y(), 3.0);
}

TEST(WorldFile, DoorInOutsideWallIsNotAWayOut) {
  const std::string text =
      replaced(kTwoRooms, "  - {at: [4, 1.5], width: 0.9}",
               "  - {at: [4, 1.5], width: 0.9}\n  - {at: [0, 1.5], width: 0.9}");
  const World w = World::loadString(text, "t.yaml");
  EXPECT_TRUE(w.isFree(0.6, 1.5, 0.15));
  EXPECT_FALSE(w.isFree(0.1, 1.5, 0.15));  // would stick out of the building
}

TEST(WorldFile, ClockwiseOutlinesAndPerEdgeWalls) {
  // The same room given clockwise with one material per edge: edge 0 (the
  // west wall, (0,0)->(0,3)) is uniform 0.2, the others 0.9.
  const char* text = R"(rooms:
  - name: r
    polygon: [[0, 0], [0, 3], [4, 3], [4, 0]]
    height: 2.5
    walls: [{albedo: 0.2}, {albedo: 0.9}, {albedo: 0.9}, {albedo: 0.9}]
    floor: {albedo: 0.5}
    ceiling: {albedo: 0.5}
)";
  const World w = World::loadString(text, "cw.yaml");
  EXPECT_GT(geo::signedArea(w.rooms[0].polygon), 0.0);
  int dark = 0;
  for (const Surface& s : w.surfaces) {
    if (s.albedo == 0.2f) {
      ++dark;
      for (const auto& c : s.corners) EXPECT_DOUBLE_EQ(c.x(), 0.0);
    }
  }
  EXPECT_EQ(dark, 1);
}

TEST(WorldFile, TexturelessRoomIsUniform) {
  const std::string text =
      replaced(kTwoRooms, "    walls: brick\n", "    walls: brick\n    textureless: true\n");
  const World w = World::loadString(text, "t.yaml");
  EXPECT_TRUE(w.rooms[0].textureless);
  for (const Surface& s : w.surfaces) {
    if (s.room == 0 && s.corners[0].z() >= 0.0 && s.albedo != 0.7f) {
      EXPECT_LT(s.texture, 0);
    }
  }
}

TEST(WorldFile, TablesFloatingBoxesAndCrops) {
  const std::string text = replaced(
      kTwoRooms, "  - {name: table,",
      "  - {name: shelf, centre: [5.5, 2.5], size: [0.6, 0.3, 0.5], elevation: 1.5,\n"
      "     material: {texture: \"skimage:brick.png\", crop: [10, 20, 100, 50], scale_m: 0.5}}\n"
      "  - {name: table,");
  World w = World::loadString(replaced(text, "facing_deg: 90, material: paint}",
                                       "facing_deg: 90, legs: 0.05, material: paint}"),
                              "t.yaml");
  ASSERT_EQ(w.textures.size(), 2u);
  EXPECT_EQ(w.textures[1].cols, 100);  // the crop
  EXPECT_EQ(w.textures[1].rows, 50);
  // Count the box faces: the floating shelf has a bottom (6 faces); the
  // table is a top slab with a bottom (6) on four legs (5 each).
  int shelf = 0, table = 0, facing_down = 0;
  for (const Surface& s : w.surfaces) {
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    for (const auto& p : s.corners) c += p / 4;
    const Eigen::Vector3d n = (s.corners[1] - s.corners[0]).cross(s.corners[3] - s.corners[0]);
    if (c.x() > 5.1 && c.x() < 5.9 && c.z() > 1.0) ++shelf, facing_down += n.z() < 0;
    if (c.x() < 2.0 && c.z() < 0.75) ++table;
  }
  EXPECT_EQ(shelf, 6);
  EXPECT_EQ(facing_down, 1);
  EXPECT_EQ(table, 26);
  // Planning keeps the whole table footprint as an obstacle.
  EXPECT_FALSE(w.isFree(1.0, 1.0, 0.1));
  expectLoadError(replaced(text, "crop: [10, 20, 100, 50]", "crop: [10, 20, 600, 50]"),
                  "boxes[0].material.crop", 21, "inside the 512 x 512 image");
}

// mirror: the texture becomes [image | image mirrored left-right] and the
// surface's scale covers both copies, so the size of one copy is unchanged.
TEST(WorldFile, MirroredRepeatDoublesThePeriod) {
  const World plain = World::loadString(kTwoRooms, "t.yaml");
  const World mirrored = World::loadString(
      replaced(kTwoRooms, "rotate_deg: 90}", "rotate_deg: 90, mirror: true}"), "t.yaml");
  ASSERT_EQ(mirrored.textures.size(), 1u);
  const cv::Mat& one = plain.textures[0];
  const cv::Mat& two = mirrored.textures[0];
  ASSERT_EQ(two.cols, 2 * one.cols);
  ASSERT_EQ(two.rows, one.rows);
  cv::Mat flipped;
  cv::flip(one, flipped, 1);
  EXPECT_EQ(cv::norm(two.colRange(0, one.cols), one, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(two.colRange(one.cols, two.cols), flipped, cv::NORM_INF), 0.0);
  double plain_scale = 0, mirrored_scale = 0;
  for (const Surface& s : plain.surfaces)
    if (s.texture == 0) plain_scale = s.texture_scale_m;
  for (const Surface& s : mirrored.surfaces)
    if (s.texture == 0) mirrored_scale = s.texture_scale_m;
  EXPECT_DOUBLE_EQ(plain_scale, 1.2);
  EXPECT_DOUBLE_EQ(mirrored_scale, 2.4);
  expectLoadError(replaced(kTwoRooms, "paint: {albedo: 0.7}", "paint: {albedo: 0.7, mirror: true}"),
                  "materials.paint.mirror", 2, "mirror needs a texture");
}

TEST(WorldFile, TextureReferences) {
  EXPECT_EQ(resolveTexturePath("skimage:brick.png", "/x"),
            fs::path("/usr/lib/python3/dist-packages/skimage/data/brick.png"));
  EXPECT_EQ(resolveTexturePath("opencv:graf1.png", "/x"),
            fs::path("/usr/share/doc/opencv-doc/examples/data/graf1.png"));
  EXPECT_EQ(resolveTexturePath("tex/a.png", "/worlds"), fs::path("/worlds/tex/a.png"));
  EXPECT_TRUE(resolveTexturePath("procedural:noise", "/x").empty());
  for (const auto& name : proceduralTextureNames()) {
    const cv::Mat t = loadTexture("procedural:" + name, ".");
    EXPECT_EQ(t.type(), CV_8UC3);
    EXPECT_EQ(t.cols, 512);
  }
  // A relative path resolves against the world file's folder.
  const fs::path dir = scratchDir();
  cv::imwrite((dir / "mine.png").string(), cv::Mat(8, 16, CV_8UC3, cv::Scalar(1, 2, 3)));
  std::ofstream(dir / "w.yaml") << replaced(kTwoRooms, "skimage:brick.png", "mine.png");
  const World w = World::loadFile(dir / "w.yaml");
  ASSERT_EQ(w.textures.size(), 1u);
  EXPECT_EQ(w.textures[0].rows, 16);  // rotated by 90 degrees
  World extra = w;
  EXPECT_EQ(extra.addTexture("skimage:astronaut.png"), 1);
  EXPECT_THROW(extra.addTexture("skimage:no_such.png"), std::runtime_error);
  fs::remove_all(dir);
}

TEST(WorldFile, TexturesAreDecodedOnceAndReadAgainWhenTheFileChanges) {
  const fs::path dir = scratchDir();
  const fs::path file = dir / "t.png";
  cv::Mat pixels(8, 16, CV_8UC3, cv::Scalar(1, 2, 3));
  pixels.at<cv::Vec3b>(0, 0) = {9, 9, 9};
  cv::imwrite(file.string(), pixels);
  const cv::Mat first = loadTexture("t.png", dir);
  const cv::Mat again = loadTexture("t.png", dir);
  EXPECT_EQ(first.data, again.data);  // one decode, shared
  // A world that rotates the texture by 180 degrees leaves the shared
  // pixels as they were.
  std::ofstream(dir / "w.yaml") << replaced(replaced(kTwoRooms, "skimage:brick.png", "t.png"),
                                            "rotate_deg: 90", "rotate_deg: 180");
  const World w = World::loadFile(dir / "w.yaml");
  ASSERT_EQ(w.textures.size(), 1u);
  EXPECT_EQ(w.textures[0].at<cv::Vec3b>(7, 15), cv::Vec3b(9, 9, 9));
  EXPECT_EQ(loadTexture("t.png", dir).at<cv::Vec3b>(0, 0), cv::Vec3b(9, 9, 9));
  // An edited file (another size) is decoded again.
  cv::imwrite(file.string(), cv::Mat(4, 4, CV_8UC3, cv::Scalar(5, 5, 5)));
  EXPECT_EQ(loadTexture("t.png", dir).cols, 4);
  fs::remove(file);
  EXPECT_THROW(loadTexture("t.png", dir), std::runtime_error);
  fs::remove_all(dir);
}

TEST(WorldFile, MakeBoxFacesOutward) {
  const auto faces = makeBox({1, 2, 0}, {0.4, 0.6, 1.8}, 0.3, 5, 0.5);
  ASSERT_EQ(faces.size(), 5u);
  const Eigen::Vector3d centre(1, 2, 0.9);
  for (const Surface& f : faces) {
    EXPECT_EQ(f.texture, 5);
    const Eigen::Vector3d n = (f.corners[1] - f.corners[0]).cross(f.corners[3] - f.corners[0]);
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    for (const auto& p : f.corners) c += p / 4;
    EXPECT_GT(n.dot(c - centre), 0.0);
  }
  // The +x face faces along the yaw.
  const Eigen::Vector3d n = (faces[kBoxPlusX].corners[1] - faces[kBoxPlusX].corners[0])
                                .cross(faces[kBoxPlusX].corners[3] - faces[kBoxPlusX].corners[0])
                                .normalized();
  EXPECT_NEAR(n.x(), std::cos(0.3), 1e-12);
  EXPECT_NEAR(n.y(), std::sin(0.3), 1e-12);
  EXPECT_NEAR(faces[kBoxTop].corners[0].z(), 1.8, 1e-12);
}

TEST(WorldFile, LevelCameraPose) {
  const Eigen::Isometry3d T = levelCameraPose({1, 2, 0.3}, M_PI / 2);
  // Optical axis (camera z) along world +y, image x to the world's -x... right of +y is +x.
  EXPECT_TRUE((T.linear().col(2) - Eigen::Vector3d(0, 1, 0)).norm() < 1e-12);
  EXPECT_TRUE((T.linear().col(0) - Eigen::Vector3d(1, 0, 0)).norm() < 1e-12);
  EXPECT_TRUE((T.linear().col(1) - Eigen::Vector3d(0, 0, -1)).norm() < 1e-12);
  EXPECT_NEAR(T.linear().determinant(), 1.0, 1e-12);
}

// --- Errors: each names the file, the key and the line ---------------------

TEST(WorldFileErrors, UnknownKey) {
  // "heigth" is on line 7 (rooms[0] starts on line 5).
  const std::string text =
      replaced(kTwoRooms, "    height: 2.5\n    walls: brick", "    heigth: 2.5\n    walls: brick");
  expectLoadError(text, "rooms[0].heigth", 7, "did you mean 'height'");
  expectLoadError(std::string(kTwoRooms) + "lights: on\n", "lights", 21, "unknown key 'lights'");
}

TEST(WorldFileErrors, MissingTexture) {
  expectLoadError(replaced(kTwoRooms, "skimage:brick.png", "skimage:no_such_brick.png"),
                  "materials.brick.texture", 3, "texture file not found");
  expectLoadError(replaced(kTwoRooms, "skimage:brick.png", "textures/missing.png"),
                  "materials.brick.texture", 3, "missing.png");
  expectLoadError(replaced(kTwoRooms, "skimage:brick.png", "procedural:marble"),
                  "materials.brick.texture", 3, "unknown procedural texture");
}

TEST(WorldFileErrors, BadPolygons) {
  // Self-intersecting (a bow tie), on line 6.
  expectLoadError(
      replaced(kTwoRooms, "[[0, 0], [4, 0], [4, 3], [0, 3]]", "[[0, 0], [4, 3], [4, 0], [0, 3]]"),
      "rooms[0].polygon", 6, "degenerate polygon");
  // Two vertices.
  expectLoadError(replaced(kTwoRooms, "[[0, 0], [4, 0], [4, 3], [0, 3]]", "[[0, 0], [4, 0]]"),
                  "rooms[0].polygon", 6, "at least 3");
  // Repeated vertex.
  expectLoadError(
      replaced(kTwoRooms, "[[0, 0], [4, 0], [4, 3], [0, 3]]", "[[0, 0], [4, 0], [4, 0], [0, 3]]"),
      "rooms[0].polygon", 6, "coincide");
  // Collinear: zero area.
  expectLoadError(
      replaced(kTwoRooms, "[[0, 0], [4, 0], [4, 3], [0, 3]]", "[[0, 0], [2, 0], [4, 0]]"),
      "rooms[0].polygon", 6, "degenerate polygon");
  // A vertex that is not a pair of numbers, on line 6.
  expectLoadError(replaced(kTwoRooms, "[[0, 0], [4, 0], [4, 3], [0, 3]]",
                           "[[0, 0], [4, 0], [4, three], [0, 3]]"),
                  "rooms[0].polygon[2][1]", 6, "expected a number, got 'three'");
  // Overlapping rooms (the east room moved 1 m west), reported on line 12.
  expectLoadError(
      replaced(kTwoRooms, "[[4, 0], [6, 0], [6, 3], [4, 3]]", "[[3, 0], [6, 0], [6, 3], [3, 3]]"),
      "rooms[1].polygon", 12, "overlaps room 'west'");
}

TEST(WorldFileErrors, YamlSyntax) {
  // An unclosed flow sequence: yaml-cpp reports where it noticed.
  const std::string text =
      replaced(kTwoRooms, "[[0, 0], [4, 0], [4, 3], [0, 3]]", "[[0, 0], [4, 0], [4, 3], [0, 3]");
  const fs::path dir = scratchDir();
  std::ofstream(dir / "w.yaml") << text;
  try {
    World::loadFile(dir / "w.yaml");
    ADD_FAILURE() << "no error";
  } catch (const ConfigError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find((dir / "w.yaml").string()), std::string::npos) << what;
    EXPECT_NE(what.find("YAML syntax error"), std::string::npos) << what;
    EXPECT_NE(what.find("line 7:"), std::string::npos) << what;
  }
  // A tab indentation error on line 2.
  expectLoadError("rooms:\n\t- name: x\n", "", 2, "YAML syntax error");
  fs::remove_all(dir);
}

TEST(WorldFileErrors, TypesAndReferences) {
  expectLoadError(
      replaced(kTwoRooms, "height: 2.5\n    walls: paint", "height: high\n    walls: paint"),
      "rooms[1].height", 13, "expected a number");
  expectLoadError(
      replaced(kTwoRooms, "height: 2.5\n    walls: paint", "height: -1\n    walls: paint"),
      "rooms[1].height", 13, "> 0");
  expectLoadError(replaced(kTwoRooms, "walls: paint", "walls: wallpaper"), "rooms[1].walls", 14,
                  "unknown material 'wallpaper'");
  expectLoadError(replaced(kTwoRooms, "    walls: brick", "    walls: [brick, paint]"),
                  "rooms[0].walls", 8, "one per polygon edge");
  expectLoadError(replaced(kTwoRooms, "{at: [4, 1.5], width: 0.9}", "{at: [3, 1.5], width: 0.9}"),
                  "doors[0].at", 18, "on no room wall");
  expectLoadError(replaced(kTwoRooms, "{at: [4, 1.5], width: 0.9}", "{at: [4, 2.8], width: 0.9}"),
                  "doors[0].width", 18, "extends past the end");
  expectLoadError(replaced(kTwoRooms, "centre: [1.0, 1.0]", "centre: [9.0, 1.0]"),
                  "boxes[0].centre", 20, "outside every room");
  expectLoadError(replaced(kTwoRooms, "paint: {albedo: 0.7}", "paint: {albedo: 0.7, scale_m: 1}"),
                  "materials.paint.scale_m", 2, "needs a texture");
  expectLoadError(replaced(kTwoRooms, "rotate_deg: 90", "rotate_deg: 45"),
                  "materials.brick.rotate_deg", 3, "90");
  expectLoadError(
      replaced(kTwoRooms, "    walls: brick\n", "    walls: brick\n    textureless: yes\n"),
      "rooms[0].textureless", 9, "expected true or false");
}

TEST(WorldFileErrors, MissingFileAndKeys) {
  try {
    World::loadFile("/nonexistent/w.yaml");
    ADD_FAILURE();
  } catch (const ConfigError& e) {
    EXPECT_EQ(e.file(), "/nonexistent/w.yaml");
  }
  // A room without 'height': reported at the room's first line (5).
  expectLoadError(replaced(kTwoRooms, "    height: 2.5\n    walls: brick\n", "    walls: brick\n"),
                  "rooms[0].height", 5, "missing required key");
}

// --- The shipped worlds ------------------------------------------------------

class ShippedWorld : public ::testing::TestWithParam<const char*> {};

TEST_P(ShippedWorld, LoadsWithFreeStartAndDrivableRoutes) {
  const World w = World::loadFile(kWorlds / GetParam());
  EXPECT_GT(w.surfaces.size(), 20u);
  EXPECT_GE(w.textures.size(), 3u);
  ASSERT_TRUE(w.has_start);
  // The robot is a 0.3 m disc; plan with 5 cm to spare.
  constexpr double kRadius = 0.2;
  EXPECT_TRUE(w.isFree(w.start.x(), w.start.y(), kRadius));
  for (const Route& r : w.routes) {
    const size_t n = r.waypoints.size();
    for (size_t i = 0; i + 1 < n + (r.closed ? 1 : 0); ++i) {
      const Eigen::Vector2d a = r.waypoints[i], b = r.waypoints[(i + 1) % n];
      for (double s = 0; s <= 1.0; s += 0.02 / std::max(0.02, (b - a).norm())) {
        const Eigen::Vector2d p = a + s * (b - a);
        ASSERT_TRUE(w.isFree(p.x(), p.y(), kRadius))
            << GetParam() << " route " << r.name << " blocked at " << p.transpose();
      }
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Worlds, ShippedWorld,
                         ::testing::Values("apartment.yaml", "living_room.yaml", "loop.yaml",
                                           "textureless.yaml"));
