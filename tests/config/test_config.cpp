// Configuration: every way a config can be wrong stops with a message naming
// the file, the key and what was expected.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>

#include "config/config_node.hpp"
#include "config/robot_config.hpp"
#include "config/stack_config.hpp"

namespace fs = std::filesystem;
using vslam::config::ConfigError;
using vslam::config::ConfigNode;
using vslam::config::InRange;

namespace {

// Expects `fn` to throw a ConfigError whose key and message contain the given parts.
template <class Fn>
void expectConfigError(Fn fn, const std::string& key, const std::string& problem_part) {
  try {
    fn();
    FAIL() << "no ConfigError for key " << key;
  } catch (const ConfigError& e) {
    EXPECT_EQ(e.key(), key) << e.what();
    EXPECT_NE(std::string(e.what()).find(problem_part), std::string::npos) << e.what();
  }
}

ConfigNode yaml(const std::string& text) { return ConfigNode::loadString(text, "test.yaml"); }

fs::path tempDir() {
  fs::path dir =
      fs::temp_directory_path() / ("vslam_test_config_" + std::to_string(::getpid()) + "_" +
                                   ::testing::UnitTest::GetInstance()->current_test_info()->name());
  fs::create_directories(dir);
  return dir;
}

void writeFile(const fs::path& p, const std::string& text) { std::ofstream(p) << text; }

}  // namespace

TEST(ConfigNode, ReadsTypedValues) {
  const ConfigNode n = yaml("a: 1.5\nb: 7\nc: true\nd: hello\ne: [1, 2, 3]\nf: FORWARD_IMAGE\n");
  EXPECT_DOUBLE_EQ(n.getDouble("a"), 1.5);
  EXPECT_EQ(n.getInt("b"), 7);
  EXPECT_TRUE(n.getBool("c"));
  EXPECT_EQ(n.getString("d"), "hello");
  EXPECT_EQ(n.getDoubles("e", 3), (std::vector<double>{1, 2, 3}));
  EXPECT_EQ(n.getChannel("f"), "FORWARD_IMAGE");
  EXPECT_NO_THROW(n.requireAllKeysUsed());
}

TEST(ConfigNode, MissingKeyNamesKeyAndExpectation) {
  const ConfigNode n = yaml("outer:\n  present: 1\n");
  const ConfigNode outer = n.child("outer");
  expectConfigError(
      [&] {
        outer.getDouble("absent", InRange{0, 10});
      },
      "outer.absent", "missing (expected a number in [0, 10])");
}

TEST(ConfigNode, ErrorsNameTheLine) {
  const ConfigNode n = yaml("a: 1\nblock:\n  x: 1\n  y: oops\n  list: [1, 2, -3]\n");
  const ConfigNode b = n.child("block");
  try {
    b.getDouble("y");
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_EQ(e.line(), 4);
    EXPECT_NE(std::string(e.what()).find("test.yaml:4: block.y:"), std::string::npos) << e.what();
  }
  try {
    b.getDoubles("list", 3, vslam::config::nonNegative());
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_EQ(e.line(), 5);
  }
  b.getDouble("x");
  try {
    b.getDouble("z");  // missing: the line of the block it belongs in
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_EQ(e.line(), 3);
  }
}

TEST(ConfigNode, MissingRequiredKeyNamesTheMisspeltOne) {
  const ConfigNode n = yaml("sigma_rotaton: 0.1\n");
  expectConfigError([&] { n.getDouble("sigma_rotation"); }, "sigma_rotation",
                    "the unknown key 'sigma_rotaton' looks like a misspelling");
}

TEST(ConfigNode, UnknownKeySuggestsClosest) {
  const ConfigNode n = yaml("block:\n  max_proj_err_rms: 3\n  min_num_pionts: 10\n");
  const ConfigNode b = n.child("block");
  b.getDouble("max_proj_err_rms");
  b.getInt("min_num_points", 10, InRange{0, 1000});
  expectConfigError([&] { b.requireAllKeysUsed(); }, "block.min_num_pionts",
                    "did you mean 'min_num_points'?");
}

TEST(ConfigNode, WrongTypeIsRejected) {
  const ConfigNode n = yaml("a: fast\nb: 2.5\nc: 'true'\nd: [1, 2]\ne: {x: 1}\n");
  expectConfigError([&] { n.getDouble("a"); }, "a", "expected a number, found 'fast'");
  expectConfigError([&] { n.getInt("b"); }, "b", "expected an integer");
  // A quoted 'true' is a string: booleans must not be strings.
  expectConfigError([&] { n.getBool("c"); }, "c", "expected true or false");
  expectConfigError([&] { n.getDoubles("d", 3); }, "d", "expected a list of 3 numbers");
  expectConfigError([&] { n.getString("e"); }, "e", "found a mapping");
}

TEST(ConfigNode, OutOfRangeIsRejected) {
  const ConfigNode n = yaml("p: 0\nq: 250\nr: [1, -2]\n");
  expectConfigError([&] { n.getDouble("p", vslam::config::positive()); }, "p", "> 0");
  expectConfigError([&] { n.getInt("q", InRange{1, 100}); }, "q", "found 250");
  expectConfigError([&] { n.getDoubles("r", 2, vslam::config::nonNegative()); }, "r[1]", "-2");
}

TEST(ConfigNode, OptionalKeysUseDefaultOnlyWhenAbsent) {
  const ConfigNode n = yaml("set: 4\nbad: -1\n");
  EXPECT_DOUBLE_EQ(n.getDouble("set", 1.0, InRange{0, 10}), 4.0);
  EXPECT_DOUBLE_EQ(n.getDouble("unset", 1.0, InRange{0, 10}), 1.0);
  // Present but invalid is an error, never a silent fallback.
  expectConfigError([&] { n.getDouble("bad", 1.0, InRange{0, 10}); }, "bad", "found -1");
}

TEST(ConfigNode, LiteralFallbackIsAFallbackNotAFlag) {
  const ConfigNode n = yaml("present: x\n");
  EXPECT_EQ(n.getString("absent", "gray8"), "gray8");
  EXPECT_EQ(n.getString("present", "gray8"), "x");
}

TEST(ConfigNode, ChannelNamesMustBeUpperSnake) {
  const ConfigNode n = yaml("c: cam_forward\n");
  expectConfigError([&] { n.getChannel("c"); }, "c", "UPPER_SNAKE_CASE");
}

TEST(ConfigNode, EnumListsAllowedWords) {
  const ConfigNode n = yaml("mode: sideways\n");
  expectConfigError(
      [&] {
        n.getEnum("mode", {"waypoints", "random"});
      },
      "mode", "expected one of: waypoints, random; found 'sideways'");
}

TEST(ConfigNode, SyntaxErrorAndMissingFile) {
  try {
    ConfigNode::loadString("a: [1, 2\nb: 3\n", "broken.yaml");
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_EQ(e.file(), "broken.yaml");
    EXPECT_NE(std::string(e.what()).find("YAML syntax error at line"), std::string::npos);
  }
  try {
    ConfigNode::loadFile("/nonexistent/vslam.yaml");
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("cannot open"), std::string::npos);
  }
}

TEST(ConfigNode, PathsResolveRelativeToTheFile) {
  const fs::path dir = tempDir();
  fs::create_directories(dir / "sub");
  writeFile(dir / "sub" / "data.txt", "x");
  writeFile(dir / "main.yaml", "data: sub/data.txt\nmissing: sub/none.txt\n");
  const ConfigNode n = ConfigNode::loadFile(dir / "main.yaml");
  EXPECT_EQ(n.getPath("data"), (dir / "sub" / "data.txt").lexically_normal());
  expectConfigError([&] { n.getPath("missing"); }, "missing", "not found");
  fs::remove_all(dir);
}

// The live stack's maps go to the user's data folder, out of the checkout:
// "$XDG_DATA_HOME/" follows the XDG base directory spec (the variable when
// absolute, else ~/.local/share) and "~/" is the home directory.
TEST(ConfigNode, PathsMayStartInTheUsersDataFolderOrHome) {
  const std::string saved_home = std::getenv("HOME") ? std::getenv("HOME") : "";
  const char* saved_xdg_env = std::getenv("XDG_DATA_HOME");
  const std::string saved_xdg = saved_xdg_env ? saved_xdg_env : "";
  const ConfigNode n =
      yaml("map: $XDG_DATA_HOME/vslam/m.db\nmine: ~/maps/m.db\nplain: $HOME/m.db\n");
  setenv("HOME", "/home/robot", 1);
  setenv("XDG_DATA_HOME", "/data/xdg", 1);
  EXPECT_EQ(n.getPath("map", false), fs::path("/data/xdg/vslam/m.db"));
  EXPECT_EQ(n.getPath("mine", false), fs::path("/home/robot/maps/m.db"));
  setenv("XDG_DATA_HOME", "relative/dir", 1);  // invalid per the spec: ignored
  EXPECT_EQ(n.getPath("map", false), fs::path("/home/robot/.local/share/vslam/m.db"));
  unsetenv("XDG_DATA_HOME");
  EXPECT_EQ(n.getPath("map", false), fs::path("/home/robot/.local/share/vslam/m.db"));
  // Only these two prefixes: anything else is a name relative to the file.
  EXPECT_EQ(n.getPath("plain", false).filename(), "m.db");
  EXPECT_NE(n.getPath("plain", false).string().find("$HOME"), std::string::npos);
  unsetenv("HOME");
  expectConfigError([&] { n.getPath("mine", false); }, "mine", "needs $HOME");
  expectConfigError([&] { n.getPath("map", false); }, "map", "needs $HOME");
  setenv("HOME", saved_home.c_str(), 1);
  if (saved_xdg_env) setenv("XDG_DATA_HOME", saved_xdg.c_str(), 1);
}

// Found by fuzzing (tests/fuzz/fuzz_config): a name the system refuses
// escaped as a std::filesystem error and ended the process.
TEST(ConfigNode, APathTheSystemRefusesIsAConfigError) {
  const ConfigNode n = yaml("long: " + std::string(5000, 'x') + "\n");
  expectConfigError([&] { n.getPath("long"); }, "long", "not found");
}

// Found by fuzzing (tests/fuzz/fuzz_config): YAML allows a list or a
// mapping as a key, and reading such a key as a name ended the process
// (an uncaught yaml-cpp exception) instead of refusing the file.
TEST(ConfigNode, AKeyThatIsNotANameIsAConfigError) {
  const ConfigNode n = yaml("block:\n  ? [a, b]\n  : 1\n  sigma: 0.1\n");
  const ConfigNode b = n.child("block");
  b.getDouble("sigma");
  expectConfigError([&] { b.requireAllKeysUsed(); }, "block.(a list as a key)",
                    "a key must be a name");
  expectConfigError([&] { b.keys(); }, "block.(a list as a key)", "a key must be a name");
  // A required key missing beside it is reported as missing.
  expectConfigError([&] { b.getDouble("sigma_rotation"); }, "block.sigma_rotation", "missing");
}

TEST(RobotConfig, ShippedRobotFileLoads) {
  const auto robot = vslam::config::RobotConfig::loadFile(fs::path(VSLAM_SOURCE_DIR) /
                                                          "config/robot/sim_two_camera.yaml");
  ASSERT_EQ(robot.cameras.size(), 2u);
  const auto& fwd = robot.camera("forward");
  EXPECT_EQ(fwd.width, 320);
  EXPECT_EQ(fwd.height, 240);
  EXPECT_NEAR(fwd.fx, 277.13, 1e-9);
  EXPECT_EQ(fwd.distortion.size(), 5u);
  // Forward camera: optical axis (camera z) along robot +x, image right
  // (camera x) along robot -y, image down (camera y) along robot -z.
  const Eigen::Matrix3d r = fwd.robot_T_camera.linear();
  EXPECT_TRUE(r.col(2).isApprox(Eigen::Vector3d(1, 0, 0), 1e-12));
  EXPECT_TRUE(r.col(0).isApprox(Eigen::Vector3d(0, -1, 0), 1e-12));
  EXPECT_TRUE(r.col(1).isApprox(Eigen::Vector3d(0, 0, -1), 1e-12));
  // Backward camera looks along -x, and its image right is robot +y.
  const Eigen::Matrix3d rb = robot.camera("backward").robot_T_camera.linear();
  EXPECT_TRUE(rb.col(2).isApprox(Eigen::Vector3d(-1, 0, 0), 1e-12));
  EXPECT_TRUE(rb.col(0).isApprox(Eigen::Vector3d(0, 1, 0), 1e-12));
  EXPECT_EQ(robot.channels.odometry, "ODOMETRY");
}

TEST(RobotConfig, PitchUpTiltsOpticalAxisUp) {
  const Eigen::Matrix3d r = vslam::config::robotRotationCamera(0, M_PI / 6, 0);
  EXPECT_NEAR(r.col(2).z(), std::sin(M_PI / 6), 1e-12);
  EXPECT_NEAR(r.col(2).x(), std::cos(M_PI / 6), 1e-12);
}

TEST(RobotConfig, BadCalibrationAndDuplicatesAreRejected) {
  const fs::path dir = tempDir();
  writeFile(dir / "cal.yml",
            "%YAML:1.0\n---\nimage_width: 320\nimage_height: 240\ncamera_matrix: !!opencv-matrix\n"
            "   rows: 2\n   cols: 2\n   dt: d\n   data: [1., 0., 0., 1.]\n");
  const std::string camera =
      "  - name: forward\n    calibration: cal.yml\n    frame_rate_hz: 10\n"
      "    position_m: [0, 0, 0.3]\n    orientation_deg: {yaw: 0, pitch: 0, roll: 0}\n"
      "    image_channel: A_IMAGE\n    calibration_channel: A_CAL\n";
  std::string channels = "channels:\n";
  for (const auto& f : vslam::config::ChannelNames::fields()) {
    std::string upper = f.key;
    for (auto& ch : upper) ch = static_cast<char>(std::toupper(ch));
    channels += std::string("  ") + f.key + ": " + upper + "\n";
  }
  writeFile(dir / "robot.yaml", "name: r\ncameras:\n" + camera + channels);
  try {
    vslam::config::RobotConfig::loadFile(dir / "robot.yaml");
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("camera_matrix: must be a 3x3"), std::string::npos)
        << e.what();
  }
  writeFile(
      dir / "cal.yml",
      "%YAML:1.0\n---\nimage_width: 320\nimage_height: 240\ncamera_matrix: !!opencv-matrix\n"
      "   rows: 3\n   cols: 3\n   dt: d\n   data: [200., 0., 160., 0., 200., 120., 0., 0., 1.]\n");
  writeFile(dir / "robot.yaml", "name: r\ncameras:\n" + camera + camera + channels);
  expectConfigError([&] { vslam::config::RobotConfig::loadFile(dir / "robot.yaml"); },
                    "cameras[1].name", "duplicate camera 'forward'");
  std::string dup_channels = channels;
  dup_channels.replace(dup_channels.find("MAP\n"), 3, "ODOMETRY");
  writeFile(dir / "robot.yaml", "name: r\ncameras:\n" + camera + dup_channels);
  expectConfigError([&] { vslam::config::RobotConfig::loadFile(dir / "robot.yaml"); },
                    "channels.map", "channel 'ODOMETRY' is used twice");
  fs::remove_all(dir);
}

// The process itself: a misspelt key exits with code 2 and names the key.
TEST(ProcessConfig, MisspeltKeyExitsTwoNamingTheKey) {
  const fs::path dir = tempDir();
  std::ifstream in(fs::path(VSLAM_SOURCE_DIR) / "config/vslam.yaml");
  std::stringstream text;
  text << in.rdbuf();
  std::string cfg = text.str();
  cfg.replace(cfg.find("sigma_rotation:"), 15, "sigma_rotaton:");
  cfg.replace(cfg.find("robot: robot/"), 13,
              "robot: " + (fs::path(VSLAM_SOURCE_DIR) / "config/robot/").string());
  writeFile(dir / "bad.yaml", cfg);
  const std::string cmd = std::string(VSLAM_BIN_DIR) + "/vslam-deadreckon --config " +
                          (dir / "bad.yaml").string() + " --lcm-url memq:// 2>&1";
  FILE* p = ::popen(cmd.c_str(), "r");
  ASSERT_NE(p, nullptr);
  std::string out;
  char buf[512];
  while (std::fgets(buf, sizeof(buf), p)) out += buf;
  const int status = ::pclose(p);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 2) << out;
  // The required key is reported missing, and the misspelt one is named.
  EXPECT_NE(out.find("processes.deadreckon.sigma_rotation: missing"), std::string::npos) << out;
  EXPECT_NE(out.find("'sigma_rotaton' looks like a misspelling"), std::string::npos) << out;
  EXPECT_NE(out.find((dir / "bad.yaml").string()), std::string::npos) << out;
  fs::remove_all(dir);
}

TEST(ConfigNode, ResolvedValuesListWhatWasReadWithDefaultsMarked) {
  const ConfigNode n = yaml("block:\n  a: 2.5\n  flag: false\n");
  const ConfigNode b = n.child("block");
  b.getDouble("a");
  b.getBool("flag");
  b.getInt("count", 7, InRange{0, 10});
  const auto values = n.resolvedValues("block.");
  ASSERT_EQ(values.size(), 3u);
  EXPECT_EQ(values[0].key, "block.a");
  EXPECT_EQ(values[0].value, "2.5");
  EXPECT_FALSE(values[0].is_default);
  EXPECT_EQ(values[1].value, "false");
  EXPECT_EQ(values[2].key, "block.count");
  EXPECT_EQ(values[2].value, "7");
  EXPECT_TRUE(values[2].is_default);
  EXPECT_TRUE(n.resolvedValues("other.").empty());
}
