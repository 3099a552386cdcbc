// The simulator end to end: what it writes, that odometry and ground truth
// agree when they should and part when they should, determinism, and the
// vslam-sim program's handling of good and bad scenarios.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <vslam/camera_calibration_t.hpp>
#include <vslam/ground_truth_pose_t.hpp>
#include <vslam/image_t.hpp>
#include <vslam/odometry_t.hpp>

#include "config/robot_config.hpp"
#include "sim/simulator.hpp"
#include "support/test_logs.hpp"

namespace fs = std::filesystem;
using namespace vslam;
using vslam::test::runCommand;

namespace {

const fs::path kSource(VSLAM_SOURCE_DIR);

template <class Msg>
Msg decode(const vslam::test::RecordedEvent& e) {
  Msg m;
  EXPECT_EQ(m.decode(e.data.data(), 0, static_cast<int>(e.data.size())),
            static_cast<int>(e.data.size()));
  return m;
}

// A free spot in the living room to start from, found by scanning the world.
Pose2 freeStart(const world::World& w) {
  const auto b = w.bounds();
  const Eigen::Vector2d c = b.center();
  for (double r = 0; r < 5; r += 0.1) {
    for (double a = 0; a < 2 * M_PI; a += 0.3) {
      const double x = c.x() + r * std::cos(a), y = c.y() + r * std::sin(a);
      if (w.isFree(x, y, 0.6)) return {x, y, 0.0};
    }
  }
  throw std::runtime_error("no free start");
}

class SimulatorTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = vslam::test::scratchDir(::testing::UnitTest::GetInstance()->current_test_info()->name());
    world_file_ = kSource / "config/worlds/living_room.yaml";
    robot_ = config::RobotConfig::loadFile(kSource / "config/robot/sim_two_camera.yaml");
    start_ = freeStart(world::World::loadFile(world_file_));
  }
  void TearDown() override { fs::remove_all(dir_); }

  fs::path writeScenario(const std::string& extra, double sigma = 0.0) {
    std::ostringstream s;
    s << "name: test\nworld: " << world_file_.string() << "\nseed: 7\n"
      << "motion:\n  mode: actions\n  start: [" << start_.x << ", " << start_.y << ", 0]\n"
      << "  actions: F L F\n  action_length_m: 0.4\n  action_error: 0\n  action_pause_s: 0.2\n"
      << "odometry:\n  sigma_translation: " << sigma << "\n  sigma_rotation: " << sigma << "\n"
      << extra;
    const fs::path file = dir_ / "scenario.yaml";
    std::ofstream(file) << s.str();
    return file;
  }

  fs::path simulate(const fs::path& scenario_file, const std::string& name) {
    const sim::Scenario sc = sim::Scenario::loadByName(scenario_file.string(), dir_);
    sim::Simulator simulator(sc, robot_, 1767225600LL * 1000000);
    const fs::path out = dir_ / name;
    sim::LogFileSink sink(out.string());
    while (simulator.step(sink)) {
    }
    return out;
  }

  fs::path dir_, world_file_;
  config::RobotConfig robot_;
  Pose2 start_;
};

}  // namespace

TEST_F(SimulatorTest, WritesEveryChannelAtItsRateInTimeOrder) {
  const auto events = vslam::test::readLog(simulate(writeScenario(""), "run.lcmlog"));
  std::map<std::string, int> count;
  int64_t last_t = 0;
  for (const auto& e : events) {
    ++count[e.channel];
    EXPECT_GE(e.timestamp, last_t);
    last_t = e.timestamp;
  }
  const int odometry = count["ODOMETRY"];
  // F 0.4 m at 0.3 m/s, L 90 deg at 45 deg/s, F 0.4 m, three 0.2 s pauses: ~5.3 s.
  EXPECT_NEAR(odometry / 50.0, 5.3, 0.2);
  EXPECT_EQ(count["GROUND_TRUTH"], odometry);
  // 10 Hz cameras on a 50 Hz clock: one frame every 5 odometry messages.
  EXPECT_EQ(count["CAM_FORWARD_IMAGE"], (odometry + 4) / 5);
  EXPECT_EQ(count["CAM_BACKWARD_IMAGE"], (odometry + 4) / 5);
  EXPECT_EQ(count["CAM_FORWARD_CALIBRATION"], (odometry + 49) / 50);
  for (const auto& e : events) {
    if (e.channel == "CAM_FORWARD_IMAGE") {
      const auto img = decode<vslam::image_t>(e);
      EXPECT_EQ(img.width, 320);
      EXPECT_EQ(img.height, 240);
      EXPECT_EQ(img.encoding, vslam::image_t::ENCODING_GRAY8);
      EXPECT_EQ(img.data_size, 320 * 240);
      EXPECT_EQ(img.camera, "forward");
    }
    if (e.channel == "CAM_BACKWARD_CALIBRATION") {
      const auto cal = decode<vslam::camera_calibration_t>(e);
      EXPECT_EQ(cal.image_channel, "CAM_BACKWARD_IMAGE");
      EXPECT_NEAR(cal.fx, 277.13, 1e-9);
      EXPECT_NEAR(cal.robot_t_camera[0], -0.10, 1e-12);
    }
  }
}

TEST_F(SimulatorTest, NoiselessOdometryIsTheTrueMotionAndKidnapIsNotInIt) {
  const auto events = vslam::test::readLog(simulate(
      writeScenario("disturbances:\n  kidnap:\n    - {at_s: 3.0, to: [" + std::to_string(start_.x) +
                    ", " + std::to_string(start_.y) + ", 180]}\n"),
      "kidnap.lcmlog"));
  std::vector<vslam::ground_truth_pose_t> gt;
  std::vector<vslam::odometry_t> odo;
  for (const auto& e : events) {
    if (e.channel == "GROUND_TRUTH") gt.push_back(decode<vslam::ground_truth_pose_t>(e));
    if (e.channel == "ODOMETRY") odo.push_back(decode<vslam::odometry_t>(e));
  }
  ASSERT_EQ(gt.size(), odo.size());
  size_t kidnap_index = 0;
  for (size_t i = 0; i < gt.size(); ++i) {
    EXPECT_EQ(gt[i].utime, odo[i].utime);
    EXPECT_EQ(odo[i].seq, static_cast<int64_t>(i));
    const double t = 1e-6 * static_cast<double>(gt[i].utime - gt[0].utime);
    const Pose2 truth{gt[i].x, gt[i].y, gt[i].theta};
    if (t < 3.0 - 1e-9) {
      // Odometry frame = the start pose: odom = start^-1 * truth.
      const Pose2 expected = start_.between(truth);
      EXPECT_NEAR(odo[i].x, expected.x, 1e-9) << "t=" << t;
      EXPECT_NEAR(odo[i].y, expected.y, 1e-9);
      EXPECT_NEAR(wrapAngle(odo[i].theta - expected.theta), 0, 1e-9);
    } else if (kidnap_index == 0) {
      kidnap_index = i;
    }
  }
  ASSERT_GT(kidnap_index, 0u);
  // The truth jumps back to the start, turned around; odometry moves on smoothly.
  EXPECT_NEAR(gt[kidnap_index].x, start_.x, 1e-9);
  EXPECT_NEAR(std::abs(gt[kidnap_index].theta), M_PI, 1e-9);
  const double odo_jump = std::hypot(odo[kidnap_index].x - odo[kidnap_index - 1].x,
                                     odo[kidnap_index].y - odo[kidnap_index - 1].y);
  EXPECT_LT(odo_jump, 0.3 * 0.02 + 1e-9);
}

TEST_F(SimulatorTest, AlternatingCamerasRenderOnlyInTheirSlots) {
  // 10 Hz shared by two cameras: forward in the first half of each 0.2 s
  // period, backward in the second; the log starts on a period boundary.
  robot_.cameras[0].alternate = {0, 2};
  robot_.cameras[1].alternate = {1, 2};
  const auto events = vslam::test::readLog(simulate(writeScenario(""), "alternating.lcmlog"));
  std::map<std::string, std::vector<int64_t>> image_times;  // since the start, microseconds
  int odometry = 0;
  const int64_t start = 1767225600LL * 1000000;
  for (const auto& e : events) {
    odometry += e.channel == "ODOMETRY";
    if (e.channel == "CAM_FORWARD_IMAGE" || e.channel == "CAM_BACKWARD_IMAGE") {
      const auto img = decode<vslam::image_t>(e);
      EXPECT_EQ(img.utime, e.timestamp);
      image_times[e.channel].push_back(img.utime - start);
    }
  }
  const auto& forward = image_times["CAM_FORWARD_IMAGE"];
  const auto& backward = image_times["CAM_BACKWARD_IMAGE"];
  // One frame per camera per 0.2 s: each at 5 Hz, together the 10 Hz of one camera.
  EXPECT_EQ(static_cast<int>(forward.size()), (odometry + 9) / 10);
  EXPECT_EQ(static_cast<int>(backward.size()), (odometry + 4) / 10);
  for (size_t i = 0; i < forward.size(); ++i) {
    EXPECT_EQ(forward[i], static_cast<int64_t>(i) * 200000) << "forward frame " << i;
  }
  for (size_t i = 0; i < backward.size(); ++i) {
    EXPECT_EQ(backward[i], 100000 + static_cast<int64_t>(i) * 200000) << "backward frame " << i;
  }
}

TEST_F(SimulatorTest, SameScenarioGivesTheSameLog) {
  const fs::path scenario = writeScenario("", 0.02);
  const auto a = vslam::test::readFileBytes(simulate(scenario, "a.lcmlog"));
  const auto b = vslam::test::readFileBytes(simulate(scenario, "b.lcmlog"));
  ASSERT_GT(a.size(), 1000000u);
  EXPECT_TRUE(a == b);
}

TEST_F(SimulatorTest, ProgramWritesLogsAndRejectsBadScenarios) {
  const std::string bin = std::string(VSLAM_BIN_DIR) + "/vslam-sim";
  const std::string cfg = (kSource / "config/vslam.yaml").string();
  std::string out;
  ASSERT_EQ(runCommand(bin + " --config " + cfg + " --scenario " + writeScenario("").string() +
                           " --duration 1 --out " + (dir_ / "p.lcmlog").string(),
                       &out),
            0)
      << out;
  int frames = 0;
  for (const auto& e : vslam::test::readLog(dir_ / "p.lcmlog")) {
    frames += e.channel == "CAM_FORWARD_IMAGE";
  }
  EXPECT_EQ(frames, 11);  // t = 0, 0.1, ..., 1.0

  const fs::path bad = dir_ / "bad.yaml";
  std::ifstream in(writeScenario(""));
  std::stringstream text;
  text << in.rdbuf();
  std::ofstream(bad) << text.str() << "colour: true\n";
  std::string err;
  EXPECT_EQ(runCommand(bin + " --config " + cfg + " --scenario " + bad.string() + " --out " +
                           (dir_ / "x.lcmlog").string(),
                       &err),
            2);
  EXPECT_NE(err.find("bad.yaml:14: colour: unknown key"), std::string::npos) << err;
}

namespace {
double meanIntensity(const vslam::image_t& img) {
  double s = 0;
  for (uint8_t v : img.data) s += v;
  return s / static_cast<double>(img.data.size());
}
std::vector<vslam::image_t> frames(const fs::path& log, const std::string& channel) {
  std::vector<vslam::image_t> out;
  for (const auto& e : vslam::test::readLog(log)) {
    if (e.channel == channel) out.push_back(decode<vslam::image_t>(e));
  }
  return out;
}
}  // namespace

TEST_F(SimulatorTest, DimmedLightsDarkenTheFramesWhileTheyLast) {
  const auto plain = frames(simulate(writeScenario("cameras: {noise_sigma: 0}\n"), "plain.lcmlog"),
                            "CAM_FORWARD_IMAGE");
  const auto dim =
      frames(simulate(writeScenario("cameras: {noise_sigma: 0}\ndisturbances:\n  lights:\n"
                                    "    - {at_s: 1.0, duration_s: 1.0, exposure: 0.4}\n"),
                      "dim.lcmlog"),
             "CAM_FORWARD_IMAGE");
  ASSERT_EQ(plain.size(), dim.size());
  for (size_t i = 0; i < plain.size(); ++i) {
    const double t = 0.1 * static_cast<double>(i);
    const double ratio = meanIntensity(dim[i]) / meanIntensity(plain[i]);
    if (t >= 1.0 && t < 2.0 - 1e-9) {
      EXPECT_NEAR(ratio, 0.4, 0.03)
          << "frame at " << t << " s";  // linear sensor, few saturated pixels
      EXPECT_NEAR(dim[i].exposure, 0.4f, 1e-6);
    } else {
      EXPECT_EQ(dim[i].data, plain[i].data) << "frame at " << t << " s";
    }
  }
}

TEST_F(SimulatorTest, WalkingPeopleChangeTheViewButNotTheRobot) {
  const fs::path a = simulate(writeScenario("cameras: {noise_sigma: 0}\n"), "empty.lcmlog");
  const fs::path b = simulate(
      writeScenario(
          "cameras: {noise_sigma: 0}\ndisturbances:\n  people: {count: 6, speed_mps: 1.0}\n"),
      "people.lcmlog");
  // Same robot motion and odometry...
  std::vector<std::vector<uint8_t>> odo_a, odo_b;
  for (const auto& e : vslam::test::readLog(a)) {
    if (e.channel == "ODOMETRY") odo_a.push_back(e.data);
  }
  for (const auto& e : vslam::test::readLog(b)) {
    if (e.channel == "ODOMETRY") odo_b.push_back(e.data);
  }
  EXPECT_EQ(odo_a, odo_b);
  // ...but six people in a 7 x 4 m room show up in some frames of the two cameras.
  int changed = 0;
  for (const char* channel : {"CAM_FORWARD_IMAGE", "CAM_BACKWARD_IMAGE"}) {
    const auto fa = frames(a, channel), fb = frames(b, channel);
    ASSERT_EQ(fa.size(), fb.size());
    for (size_t i = 0; i < fa.size(); ++i) changed += fa[i].data != fb[i].data;
  }
  EXPECT_GT(changed, 0);
}

TEST_F(SimulatorTest, TrajectoryModeReplaysTheFileAsGroundTruth) {
  // A straight 1 m drive in 5 s, given as a TUM file, with its own odometry.
  const fs::path traj = dir_ / "traj.tum", odom = dir_ / "odom.tum";
  {
    std::ofstream t(traj), o(odom);
    for (int i = 0; i <= 50; ++i) {
      const double s = 0.1 * i;
      t << 100.0 + s << " " << start_.x + 0.2 * s << " " << start_.y << " 0 0 0 0 1\n";
      o << 100.0 + s << " " << 0.21 * s << " 0 0 0 0 0 1\n";  // wheels over-read by 5%
    }
  }
  const fs::path scenario = dir_ / "traj.yaml";
  std::ofstream(scenario) << "name: t\nworld: " << world_file_.string()
                          << "\nmotion:\n  mode: trajectory\n  trajectory_file: traj.tum\n"
                             "  odometry_file: odom.tum\nodometry:\n  sigma_translation: 0.05\n"
                             "  sigma_rotation: 0.05\n";
  const auto events = vslam::test::readLog(simulate(scenario, "traj.lcmlog"));
  std::vector<vslam::ground_truth_pose_t> gt;
  std::vector<vslam::odometry_t> odo;
  for (const auto& e : events) {
    if (e.channel == "GROUND_TRUTH") gt.push_back(decode<vslam::ground_truth_pose_t>(e));
    if (e.channel == "ODOMETRY") odo.push_back(decode<vslam::odometry_t>(e));
  }
  ASSERT_GE(gt.size(), 250u);
  for (size_t i = 0; i < gt.size(); ++i) {
    const double s = 0.02 * static_cast<double>(i);
    if (s > 5.0) break;
    EXPECT_NEAR(gt[i].x, start_.x + 0.2 * s, 1e-9) << i;
    EXPECT_NEAR(odo[i].x, 0.21 * s, 1e-9) << i;  // the recorded odometry, not simulated noise
  }
}
