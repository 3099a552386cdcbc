// Real pixels through the live stack: OpenCV's recorded street scene
// (opencv-doc's vtest.avi, 768x576, 10 fps, a fixed camera) is the forward
// camera of the one-camera robot (config/robot/one_camera.yaml), played by
// vslam-camera's video: source in real time (the odometry is real time: a
// faster video would stamp frames ahead of it, and the front-end uses only
// frames with an odometry pose) and resized to the robot file's 320x240; an odometry file of a slow
// turn in place is fed through scripts/lib/odometry-input into vslam-odometry-bridge;
// vslam-frontend and vslam-appearance consume both over UDP multicast on loopback in a private
// network namespace (skipped where unshare --net is not permitted).
//
// The intrinsics: the robot file's calibration is the simulated 320x240
// camera's; vtest.avi's own is unknown. Resizing 768x576 to 320x240 keeps the
// aspect ratio, so the images are what that calibration declares them to be
// in size; features and appearance histograms do not depend on the focal
// length, metric measurements would (none are expected: a fixed camera and a
// robot turning in place give no baseline for landmarks).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>
#include <vslam/health_t.hpp>

#include "process_harness.hpp"

namespace tt = vslam::transport_test;
namespace fs = std::filesystem;

namespace {

constexpr const char* kUrl = "udpm://239.255.76.67:7667?ttl=0&recv_buf_size=8388608";
constexpr const char* kVideo = "/usr/share/doc/opencv-doc/examples/data/vtest.avi";

std::string readFile(const fs::path& file) {
  std::ifstream in(file);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

double metric(const vslam::health_t& h, const std::string& name, double absent = -1) {
  for (const auto& m : h.metrics) {
    if (m.name == name) return m.value;
  }
  return absent;
}

// config/vslam-one-camera.yaml with its robot file by absolute path, the
// forward camera playing `video`, no landmark DB (the front-end alone), and
// the appearance map in the test's folder.
std::string writeConfig(const tt::TempDir& dir, const std::string& video) {
  const std::string kShippedAppearanceMap =
      "    map_file: $XDG_DATA_HOME/vslam/appearance.vslam-appearance";
  std::istringstream in(readFile(fs::path(VSLAM_SOURCE_DIR) / "config/vslam-one-camera.yaml"));
  std::ostringstream out;
  std::string line;
  int replaced = 0;
  while (std::getline(in, line)) {
    if (line.rfind("robot: robot/one_camera.yaml", 0) == 0) {
      line = std::string("robot: ") + VSLAM_SOURCE_DIR + "/config/robot/one_camera.yaml";
      ++replaced;
    } else if (line.rfind("    source: v4l2:/dev/video0", 0) == 0) {
      line = "    source: video:" + video;
      ++replaced;
    } else if (line.rfind("    landmark_db: required", 0) == 0) {
      line = "    landmark_db: none";
      ++replaced;
    } else if (line.rfind(kShippedAppearanceMap, 0) == 0) {
      line = "    map_file: " + dir.path() + "/appearance.vslam-appearance";  // not the user's
      ++replaced;
    }
    out << line << "\n";
  }
  EXPECT_EQ(replaced, 4) << "config/vslam-one-camera.yaml changed: update this test";
  const std::string file = dir.path() + "/vslam.yaml";
  std::ofstream(file) << out.str();
  return file;
}

// A turn in place at 0.4 rad/s, 20 lines a second for 60 s ("t x y theta").
std::string writeOdometry(const tt::TempDir& dir) {
  const std::string file = dir.path() + "/odometry.txt";
  std::ofstream out(file);
  out << "# a slow turn in place: t x y theta\n";
  for (int i = 0; i <= 1200; ++i) {
    const double t = 0.05 * i;
    const double theta = std::remainder(0.4 * t, 2 * M_PI);
    out << t << " 0 0 " << theta << "\n";
  }
  return file;
}

class RealPixelsLive : public tt::NetnsTest {};

TEST_F(RealPixelsLive, VideoThroughCameraDriverIntoFrontendAndAppearance) {
  if (!fs::exists(kVideo)) GTEST_SKIP() << kVideo << " is missing (Debian package opencv-doc)";
  VSLAM_IN_FRESH_NETNS();
  tt::TempDir dir;
  const std::string config = writeConfig(dir, kVideo);
  const std::string odometry = writeOdometry(dir);

  tt::TestBus bus(kUrl);
  ASSERT_TRUE(bus.good()) << "cannot open LCM at " << kUrl;
  std::map<std::string, vslam::health_t> last;  // per instance
  std::map<std::string, int> worst_level;
  std::map<std::string, double> max_features, max_states;
  bus.subscribe("HEALTH", [&](const std::string&, const uint8_t* data, size_t size) {
    vslam::health_t m;
    ASSERT_EQ(m.decode(data, 0, static_cast<int>(size)), static_cast<int>(size));
    worst_level[m.instance] = std::max<int>(worst_level[m.instance], m.level);
    max_features[m.instance] = std::max(max_features[m.instance], metric(m, "features_per_frame"));
    max_states[m.instance] = std::max(max_states[m.instance], metric(m, "states"));
    last[m.instance] = m;
  });

  const std::string bin = VSLAM_BIN_DIR;
  auto stage = [&](const std::string& program, const std::string& instance) {
    return std::vector<std::string>{bin + "/" + program, "--config", config, "--instance", instance,
                                    "--lcm-url",         kUrl};
  };
  struct Process {
    std::string instance;
    tt::Child child;
    fs::path log;
  };
  std::vector<Process> procs;
  auto start = [&](const std::string& instance, std::vector<std::string> argv,
                   const std::vector<std::pair<std::string, std::string>>& env = {}) {
    const fs::path log = dir.path() + "/" + instance + ".log";
    procs.push_back({instance, tt::Child::spawn(argv, env, log.string()), log});
    ASSERT_TRUE(procs.back().child.valid()) << instance;
  };
  auto outputs = [&] {
    std::string all = "last HEALTH per instance:\n";
    for (const auto& [instance, h] : last) {
      all += "  " + instance + " level " + std::to_string(h.level) + " '" + h.message + "':";
      for (const auto& m : h.metrics) all += " " + m.name + "=" + std::to_string(m.value);
      all += "\n";
    }
    for (const auto& p : procs) all += "--- " + p.instance + ":\n" + readFile(p.log);
    return all;
  };
  // Consumers first, the sources last (as the robot profile orders them).
  start("frontend_forward", stage("vslam-frontend", "frontend_forward"));
  start("appearance", stage("vslam-appearance", "appearance"));
  auto bridge = stage("vslam-odometry-bridge", "odometry_bridge");
  bridge.insert(bridge.begin(), std::string(VSLAM_SOURCE_DIR) + "/scripts/lib/odometry-input");
  start("odometry_bridge", bridge, {{"VSLAM_ODOMETRY_FILE", odometry}});
  start("camera_forward", stage("vslam-camera", "camera_forward"));

  // Until the front-end has found features in real frames and appearance
  // SLAM has made states of them (a snapshot after each quarter turn, ~4 s).
  const bool done = bus.spinUntil(
      [&] {
        for (auto& p : procs) {
          if (!p.child.running()) return true;
        }
        return max_features["frontend_forward"] > 0 && max_states["appearance"] >= 2;
      },
      45.0);
  for (auto& p : procs) {
    ASSERT_TRUE(p.child.running())
        << p.instance << " " << tt::describeStatus(*p.child.status()) << "\n"
        << outputs();
  }
  ASSERT_TRUE(done) << "no features or appearance steps within 45 s\n" << outputs();
  bus.spinFor(1.5);  // one more health period of each

  // The camera decoded and resized real frames, none of the wrong size.
  ASSERT_TRUE(last.count("camera_forward")) << outputs();
  const auto& cam = last["camera_forward"];
  EXPECT_GT(metric(cam, "frames_total"), 20);
  EXPECT_EQ(metric(cam, "source_open"), 1);
  EXPECT_EQ(metric(cam, "dropped_size"), 0);
  EXPECT_EQ(metric(cam, "read_errors"), 0);
  // The front-end processed them and found features; nothing malformed.
  const auto& fe = last["frontend_forward"];
  EXPECT_GT(metric(fe, "frames_processed", 0) + metric(fe, "frames_dropped", 0), 0);
  EXPECT_GT(max_features["frontend_forward"], 50) << "SIFT features per frame";
  EXPECT_EQ(fe.messages_malformed, 0) << fe.message;
  EXPECT_LT(worst_level["frontend_forward"], vslam::health_t::LEVEL_ERROR) << fe.message;
  // Appearance SLAM stepped on the real images with the bridged odometry.
  const auto& app = last["appearance"];
  EXPECT_GE(max_states["appearance"], 2);
  EXPECT_EQ(app.messages_malformed, 0) << app.message;
  EXPECT_LT(worst_level["appearance"], vslam::health_t::LEVEL_ERROR) << app.message;
  // The bridge accepted every line of the file so far, rejected none.
  const auto& odo = last["odometry_bridge"];
  EXPECT_GT(metric(odo, "lines_accepted"), 20);
  EXPECT_EQ(metric(odo, "lines_rejected"), 0);

  // A clean stop: SIGINT, exit 0, no crash.
  for (auto it = procs.rbegin(); it != procs.rend(); ++it) it->child.sendSignal(SIGINT);
  for (auto& p : procs) {
    const auto status = p.child.waitFor(15.0);
    ASSERT_TRUE(status.has_value()) << p.instance << " still running 15 s after SIGINT";
    EXPECT_TRUE(tt::exitedWith(status, 0))
        << p.instance << ": " << tt::describeStatus(*status) << "\n"
        << readFile(p.log);
  }
}

}  // namespace
