// The camera stage: its configuration checks (exit 2 naming the key, the two
// sizes when the images would not match the robot file), and vslam-camera as
// a process over UDP multicast in a private network namespace: a generated
// video becomes vslam.image_t at the robot file's size, with the calibration
// at 1 Hz, and SIGTERM stops it cleanly.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <csignal>
#include <fstream>
#include <vslam/camera_calibration_t.hpp>
#include <vslam/image_t.hpp>

#include "capture_test_util.hpp"
#include "config/stack_config.hpp"
#include "process_harness.hpp"
#include "stages/builtin_stages.hpp"

namespace {

using namespace vslam;
using namespace vslam::capture_test;
namespace tt = vslam::transport_test;

constexpr const char* kUrl = "udpm://239.255.76.67:7667?ttl=0&recv_buf_size=8388608";

// A stack config with the repository's robot (forward camera: 320x240) and
// one camera block.
fs::path writeConfig(const fs::path& dir, const std::string& block) {
  const fs::path file = dir / "vslam.yaml";
  std::ofstream(file) << "robot: " << VSLAM_SOURCE_DIR << "/config/robot/sim_two_camera.yaml\n"
                      << "processes:\n  cam:\n    role: camera\n"
                      << block;
  return file;
}

// The configuration error building the stage gives, or "" if it builds.
std::string configError(const fs::path& config) {
  try {
    const auto stack = config::StackConfig::loadFile(config);
    stages::driverStages().create(stack, "cam", "camera");
    return "";
  } catch (const config::ConfigError& e) {
    return e.what();
  }
}

class CameraStageConfig : public ::testing::Test {
 protected:
  void SetUp() override { writeVideo(dir_.path() / "v.avi", 5, 10.0, {640, 480}); }
  TempDir dir_;
};

TEST_F(CameraStageConfig, ABlockThatFitsBuilds) {
  EXPECT_EQ(configError(writeConfig(dir_.path(),
                                    "    camera: forward\n    source: video:v.avi\n"
                                    "    encoding: jpeg\n    width: 320\n    height: 240\n")),
            "");
  EXPECT_EQ(configError(writeConfig(dir_.path(),
                                    "    camera: forward\n    source: video:v.avi\n"
                                    "    encoding: jpeg\n    width: 320\n    height: 240\n"
                                    "    max_fps: 10\n    alternate: {slot: 1, slots: 2}\n")),
            "");
}

TEST_F(CameraStageConfig, ErrorsNameTheKey) {
  const std::vector<std::pair<std::string, std::vector<std::string>>> cases{
      {"    camera: left\n    source: video:v.avi\n    encoding: gray8\n",
       {"processes.cam.camera", "no camera 'left'", "forward, backward"}},
      {"    camera: forward\n    source: v4l2:/dev/video-vslam-none\n    encoding: gray8\n",
       {"processes.cam.source", "no device /dev/video-vslam-none"}},
      {"    camera: forward\n    source: webcam:0\n    encoding: gray8\n",
       {"processes.cam.source", "unknown source kind 'webcam'"}},
      {"    camera: forward\n    source: video:v.avi\n    encoding: rgb\n",
       {"processes.cam.encoding"}},
      // A misspelt key is named before the source is opened (640x480 would not fit either).
      {"    camera: forward\n    source: video:v.avi\n    encoding: gray8\n    max_fsp: 3\n",
       {"processes.cam.max_fsp: unknown key", "did you mean 'max_fps'"}},
      {"    camera: forward\n    source: video:v.avi\n    encoding: gray8\n    width: 320\n",
       {"processes.cam.height", "give both width and height"}},
      {"    camera: forward\n    source: video:v.avi\n    encoding: gray8\n    v4l2:\n"
       "      width: 640\n",
       {"processes.cam.v4l2", "device settings need a v4l2: source"}},
      // Taking turns: the shared rate, and a slot of the slots.
      {"    camera: forward\n    source: video:v.avi\n    encoding: gray8\n    width: 320\n"
       "    height: 240\n    alternate: {slot: 0, slots: 2}\n",
       {"processes.cam.alternate", "needs max_fps > 0"}},
      {"    camera: forward\n    source: video:v.avi\n    encoding: gray8\n    width: 320\n"
       "    height: 240\n    max_fps: 10\n    alternate: {slot: 2, slots: 2}\n",
       {"processes.cam.alternate.slot", "slot 2 of 2 slots", "0..1"}},
      {"    camera: forward\n    source: video:v.avi\n    encoding: gray8\n    width: 320\n"
       "    height: 240\n    max_fps: 10\n    alternate: {slot: 0}\n",
       {"processes.cam.alternate.slots"}},
  };
  for (const auto& [block, wanted] : cases) {
    const std::string error = configError(writeConfig(dir_.path(), block));
    for (const auto& w : wanted) EXPECT_NE(error.find(w), std::string::npos) << block << error;
  }
}

// Item 4 of the issue: an image size other than the robot file's is an
// error naming both sizes, never silently ignored.
TEST_F(CameraStageConfig, ASizeOtherThanTheRobotFilesNamesBoth) {
  std::string error = configError(writeConfig(
      dir_.path(), "    camera: forward\n    source: video:v.avi\n    encoding: gray8\n"));
  EXPECT_NE(error.find("processes.cam.source"), std::string::npos) << error;
  EXPECT_NE(error.find("640x480"), std::string::npos) << error;
  EXPECT_NE(error.find("calibrated for 320x240"), std::string::npos) << error;
  EXPECT_NE(error.find("set width: 320 and height: 240"), std::string::npos) << error;

  error = configError(writeConfig(dir_.path(),
                                  "    camera: forward\n    source: video:v.avi\n"
                                  "    encoding: gray8\n    width: 160\n    height: 120\n"));
  EXPECT_NE(error.find("processes.cam.width"), std::string::npos) << error;
  EXPECT_NE(error.find("resized to 160x120"), std::string::npos) << error;
  EXPECT_NE(error.find("320x240"), std::string::npos) << error;
  EXPECT_NE(error.find("the calibration would be fx"), std::string::npos) << error;
}

TEST_F(CameraStageConfig, ProcessExitsTwoNamingTheKey) {
  const fs::path config = writeConfig(
      dir_.path(), "    camera: forward\n    source: video:missing.avi\n    encoding: gray8\n");
  const fs::path out = dir_.path() / "out.txt";
  tt::Child child = tt::Child::spawn({std::string(VSLAM_BIN_DIR) + "/vslam-camera", "--config",
                                      config.string(), "--instance", "cam", "--lcm-url", "memq://"},
                                     {}, out.string());
  const auto status = child.waitFor(30);
  ASSERT_TRUE(status.has_value());
  std::ifstream in(out);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_TRUE(tt::exitedWith(status, 2)) << tt::describeStatus(*status) << text;
  EXPECT_NE(text.find("processes.cam.source"), std::string::npos) << text;
  EXPECT_NE(text.find("no video file"), std::string::npos) << text;
}

class CameraLive : public tt::NetnsTest {};

TEST_F(CameraLive, PublishesImagesAndCalibrationOverMulticast) {
  VSLAM_IN_FRESH_NETNS();
  TempDir dir;
  writeVideo(dir.path() / "v.avi", 10, 20.0, {640, 480});
  const fs::path config = writeConfig(
      dir.path(),
      "    camera: forward\n    source: video:v.avi\n    encoding: gray8\n    width: 320\n"
      "    height: 240\n    loop: true\n");
  tt::TestBus bus(kUrl);
  ASSERT_TRUE(bus.good());
  std::vector<vslam::image_t> images;
  int calibrations = 0;
  vslam::camera_calibration_t calibration{};
  bus.subscribe("CAM_FORWARD_IMAGE", [&](const std::string&, const uint8_t* data, size_t size) {
    vslam::image_t m;
    if (m.decode(data, 0, static_cast<int>(size)) == static_cast<int>(size)) images.push_back(m);
  });
  bus.subscribe(
      "CAM_FORWARD_CALIBRATION", [&](const std::string&, const uint8_t* data, size_t size) {
        if (calibration.decode(data, 0, static_cast<int>(size)) == static_cast<int>(size)) {
          ++calibrations;
        }
      });
  tt::Child camera = tt::Child::spawn({std::string(VSLAM_BIN_DIR) + "/vslam-camera", "--config",
                                       config.string(), "--instance", "cam", "--lcm-url", kUrl});
  ASSERT_TRUE(bus.spinUntil([&] { return images.size() >= 25 && calibrations >= 1; }, 20.0))
      << images.size() << " images, " << calibrations << " calibrations; vslam-camera "
      << (camera.running() ? "running" : tt::describeStatus(*camera.status()));
  camera.sendSignal(SIGTERM);
  const auto status = camera.waitFor(10.0);
  ASSERT_TRUE(status.has_value()) << "vslam-camera ignored SIGTERM";
  EXPECT_TRUE(tt::exitedWith(status, 0)) << tt::describeStatus(*status);

  for (size_t i = 0; i < images.size(); ++i) {
    const auto& m = images[i];
    EXPECT_EQ(m.camera, "forward");
    EXPECT_EQ(m.width, 320);
    EXPECT_EQ(m.height, 240);
    EXPECT_EQ(m.encoding, vslam::image_t::ENCODING_GRAY8);
    EXPECT_EQ(m.row_stride, 320);
    ASSERT_EQ(m.data.size(), 320u * 240u);
    // The pixels of the frame the sequence number says (the video loops every 10).
    const cv::Mat gray(240, 320, CV_8UC1, const_cast<uint8_t*>(m.data.data()));
    EXPECT_EQ(indexOf(gray), m.seq % 10) << "image " << i;
    if (i > 0) {
      EXPECT_EQ(m.seq, images[i - 1].seq + 1);
      EXPECT_NEAR(m.utime - images[i - 1].utime, 50000, 1000);
    }
  }
  EXPECT_EQ(calibration.camera, "forward");
  EXPECT_EQ(calibration.image_channel, "CAM_FORWARD_IMAGE");
  EXPECT_EQ(calibration.width, 320);
  EXPECT_EQ(calibration.height, 240);
  EXPECT_GT(calibration.fx, 0);
}

}  // namespace
