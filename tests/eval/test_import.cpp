// vslam-import round trip: a small TUM-RGB-D-layout folder (generated PNGs,
// rgb.txt, groundtruth.txt of the camera, odometry of the base) becomes a log
// whose images are pixel-exact, poses planar and converted to the base,
// calibration at 1 Hz, events in time order; and every bad input is named.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <vslam/camera_calibration_t.hpp>
#include <vslam/ground_truth_pose_t.hpp>
#include <vslam/image_t.hpp>
#include <vslam/odometry_t.hpp>

#include "config/robot_config.hpp"
#include "eval/import_cli.hpp"
#include "eval_test_util.hpp"

namespace fs = std::filesystem;
using vslam::test::contains;
using vslam::test::LoggedEvent;
using vslam::test::runProgram;

namespace {

constexpr int64_t kT0 = 1305031102000000;  // microseconds
constexpr int kImages = 6;                 // one every 0.5 s from kT0 + 10 ms
constexpr int kWidth = 64, kHeight = 48;

double wrap(double a) {
  a = std::remainder(a, 2 * M_PI);
  return a <= -M_PI ? a + 2 * M_PI : a;
}

std::string stamp(int64_t utime) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%lld.%06lld", static_cast<long long>(utime / 1000000),
                static_cast<long long>(utime % 1000000));
  return buf;
}

int64_t imageUtime(int i) { return kT0 + 10000 + i * 500000; }

// Robot base in the world: drives and turns, heading crossing +-pi.
struct BasePose {
  double x, y, theta;
};
BasePose groundTruthBase(double s) { return {0.5 * s, 0.2 * s, wrap(2.8 + 0.3 * s)}; }
BasePose odometryBase(double s) { return {0.4 * s, -0.1 * s, -0.5 * s}; }

// Extrinsics used below: camera 0.1 m ahead, 0.3 m up, pitched 10 degrees
// down. Columns of the level forward camera: x right = -y_robot, y down =
// -z_robot, z optical axis = +x_robot; pitch down = rotation about +y_robot.
Eigen::Isometry3d robotTCamera() {
  Eigen::Matrix3d forward;
  forward << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(10.0 * M_PI / 180, Eigen::Vector3d::UnitY()).matrix() * forward;
  T.translation() = Eigen::Vector3d(0.1, 0.0, 0.3);
  return T;
}

Eigen::Isometry3d planar(const BasePose& p) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(p.theta, Eigen::Vector3d::UnitZ()).matrix();
  T.translation() = Eigen::Vector3d(p.x, p.y, 0);
  return T;
}

std::string tumLine(int64_t utime, const Eigen::Isometry3d& T) {
  const Eigen::Quaterniond q(T.linear());
  char buf[256];
  std::snprintf(buf, sizeof(buf), "%s %.9f %.9f %.9f %.12f %.12f %.12f %.12f\n",
                stamp(utime).c_str(), T.translation().x(), T.translation().y(), T.translation().z(),
                q.x(), q.y(), q.z(), q.w());
  return buf;
}

cv::Mat grayImage(int i) {
  cv::Mat img(kHeight, kWidth, CV_8UC1);
  for (int y = 0; y < kHeight; ++y) {
    for (int x = 0; x < kWidth; ++x)
      img.at<uint8_t>(y, x) = static_cast<uint8_t>((i * 37 + x * 3 + y * 5 + x * y) % 256);
  }
  return img;
}

cv::Mat colourImage(int i) {
  cv::Mat img(kHeight, kWidth, CV_8UC3);
  for (int y = 0; y < kHeight; ++y) {
    for (int x = 0; x < kWidth; ++x) {
      img.at<cv::Vec3b>(y, x) = {static_cast<uint8_t>(x * 4 + i), static_cast<uint8_t>(y * 5),
                                 static_cast<uint8_t>((x * y + 17 * i) % 256)};
    }
  }
  return img;
}

void writeText(const fs::path& p, const std::string& text) { std::ofstream(p) << text; }

void writeCalibration(const fs::path& p, int width, int height) {
  std::ostringstream os;
  os << "%YAML:1.0\n---\nimage_width: " << width << "\nimage_height: " << height
     << "\ncamera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n"
        "   data: [ 50., 0., 31.5, 0., 51., 23.5, 0., 0., 1. ]\n"
        "distortion_coefficients: !!opencv-matrix\n   rows: 1\n   cols: 5\n   dt: d\n"
        "   data: [ -0.1, 0.02, 0.001, -0.002, 0.003 ]\n";
  writeText(p, os.str());
}

// Writes the folder: rgb/<i>.png, rgb.txt (with TUM's three header lines),
// groundtruth.txt at 10 Hz for 3 s (camera poses), odometry.txt at 50 Hz
// (base poses, 5 ms after the ground truth's clock), calib.yml.
void writeDataset(const fs::path& dir, bool colour) {
  fs::create_directories(dir / "rgb");
  std::string list = "# color images\n# file: 'test.bag'\n# timestamp filename\n";
  for (int i = 0; i < kImages; ++i) {
    const std::string name = "rgb/" + stamp(imageUtime(i)) + ".png";
    ASSERT_TRUE(cv::imwrite((dir / name).string(), colour ? colourImage(i) : grayImage(i)));
    list += stamp(imageUtime(i)) + " " + name + "\n";
  }
  writeText(dir / "rgb.txt", list);
  std::string gt = "# ground truth trajectory\n# timestamp tx ty tz qx qy qz qw\n";
  for (int k = 0; k <= 30; ++k) {
    gt += tumLine(kT0 + k * 100000, planar(groundTruthBase(0.1 * k)) * robotTCamera());
  }
  writeText(dir / "groundtruth.txt", gt);
  std::string odo;
  for (int k = 0; k <= 150; ++k) {
    odo += tumLine(kT0 + 5000 + k * 20000, planar(odometryBase(0.02 * k)));
  }
  writeText(dir / "odometry.txt", odo);
  writeCalibration(dir / "calib.yml", kWidth, kHeight);
}

template <class Msg>
Msg decode(const LoggedEvent& ev) {
  Msg m;
  EXPECT_EQ(m.decode(ev.data.data(), 0, static_cast<int>(ev.data.size())),
            static_cast<int>(ev.data.size()))
      << ev.channel;
  return m;
}

struct CliResult {
  int code;
  std::string out, err;
};

CliResult runImport(const std::vector<std::string>& args) {
  std::ostringstream out, err;
  const int code = vslam::eval::runImportCli(args, out, err);
  return {code, out.str(), err.str()};
}

class Import : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = vslam::test::freshDir(std::string("import_") +
                                 ::testing::UnitTest::GetInstance()->current_test_info()->name());
    data_ = dir_ / "dataset";
    log_ = dir_ / "out.lcmlog";
    // The default stack config comes from the environment or the working
    // directory (./config/vslam.yaml): neither here.
    ::unsetenv("VSLAM_CONFIG");
    cwd_ = fs::current_path();
    fs::current_path(dir_);
  }
  void TearDown() override {
    fs::current_path(cwd_);
    fs::remove_all(dir_);
  }
  std::vector<std::string> baseArgs() const {
    return {data_.string(), "--calibration", (data_ / "calib.yml").string(), "--out",
            log_.string()};
  }
  fs::path dir_, data_, log_, cwd_;
};

}  // namespace

TEST_F(Import, RoundTripGray8) {
  writeDataset(data_, false);
  auto args = baseArgs();
  for (const char* a :
       {"--odometry", "", "--camera-position", "0.1,0,0.3", "--camera-orientation", "0,-10,0"}) {
    args.push_back(*a ? a : (data_ / "odometry.txt").string());
  }
  const auto r = runImport(args);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(contains(r.out, "6 images")) << r.out;

  const auto events = vslam::test::readLogEvents(log_);
  std::map<std::string, int> counts;
  int64_t last = 0;
  std::size_t first_image = 0, first_calibration = events.size();
  for (std::size_t i = 0; i < events.size(); ++i) {
    EXPECT_GE(events[i].timestamp, last) << "event " << i << " out of time order";
    last = events[i].timestamp;
    if (counts[events[i].channel]++ == 0) {
      if (events[i].channel == "CAM_FORWARD_IMAGE") first_image = i;
      if (events[i].channel == "CAM_FORWARD_CALIBRATION") first_calibration = i;
    }
  }
  EXPECT_EQ(counts["CAM_FORWARD_IMAGE"], kImages);
  EXPECT_EQ(counts["CAM_FORWARD_CALIBRATION"], 3);  // at 0.01, 1.01, 2.01 s; images end at 2.51 s
  EXPECT_EQ(counts["GROUND_TRUTH"], 31);
  EXPECT_EQ(counts["ODOMETRY"], 151);
  EXPECT_EQ(counts.size(), 4u);
  EXPECT_LT(first_calibration, first_image);  // front-ends get the calibration first

  int image_seq = 0, gt_seq = 0, odo_seq = 0, calib_n = 0;
  for (const auto& ev : events) {
    if (ev.channel == "CAM_FORWARD_IMAGE") {
      const auto m = decode<vslam::image_t>(ev);
      EXPECT_EQ(m.utime, ev.timestamp);
      EXPECT_EQ(m.utime, imageUtime(image_seq));
      EXPECT_EQ(m.seq, image_seq);
      EXPECT_EQ(m.camera, "forward");
      EXPECT_EQ(m.width, kWidth);
      EXPECT_EQ(m.height, kHeight);
      EXPECT_EQ(m.row_stride, kWidth);
      EXPECT_EQ(m.encoding, vslam::image_t::ENCODING_GRAY8);
      ASSERT_EQ(m.data_size, kWidth * kHeight);
      const cv::Mat got(kHeight, kWidth, CV_8UC1, const_cast<uint8_t*>(m.data.data()));
      EXPECT_EQ(cv::norm(got, grayImage(image_seq), cv::NORM_INF), 0.0) << "image " << image_seq;
      ++image_seq;
    } else if (ev.channel == "CAM_FORWARD_CALIBRATION") {
      const auto m = decode<vslam::camera_calibration_t>(ev);
      EXPECT_EQ(m.utime, ev.timestamp);
      EXPECT_EQ(m.utime, imageUtime(0) + calib_n * 1000000);
      EXPECT_EQ(m.camera, "forward");
      EXPECT_EQ(m.image_channel, "CAM_FORWARD_IMAGE");
      EXPECT_EQ(m.width, kWidth);
      EXPECT_EQ(m.height, kHeight);
      EXPECT_NEAR(m.frame_rate, 2.0, 1e-9);
      EXPECT_EQ(m.fx, 50.0);
      EXPECT_EQ(m.fy, 51.0);
      EXPECT_EQ(m.cx, 31.5);
      EXPECT_EQ(m.cy, 23.5);
      ASSERT_EQ(m.num_distortion, 5);
      EXPECT_EQ(m.distortion[0], -0.1);
      EXPECT_EQ(m.distortion[4], 0.003);
      EXPECT_NEAR(m.robot_t_camera[0], 0.1, 1e-12);
      EXPECT_NEAR(m.robot_t_camera[2], 0.3, 1e-12);
      const Eigen::Quaterniond q(m.robot_q_camera[0], m.robot_q_camera[1], m.robot_q_camera[2],
                                 m.robot_q_camera[3]);
      EXPECT_LT((q.toRotationMatrix() - robotTCamera().linear()).norm(), 1e-9);
      ++calib_n;
    } else if (ev.channel == "GROUND_TRUTH") {
      const auto m = decode<vslam::ground_truth_pose_t>(ev);
      const BasePose p = groundTruthBase(0.1 * gt_seq);
      EXPECT_EQ(m.utime, ev.timestamp);
      EXPECT_EQ(m.utime, kT0 + gt_seq * 100000);
      EXPECT_EQ(m.seq, gt_seq);
      EXPECT_NEAR(m.x, p.x, 1e-7);  // the camera pose moved back to the base
      EXPECT_NEAR(m.y, p.y, 1e-7);
      EXPECT_NEAR(m.z, 0.0, 1e-7);
      EXPECT_NEAR(std::abs(wrap(m.theta - p.theta)), 0.0, 1e-7);
      EXPECT_LE(m.theta, M_PI);
      EXPECT_GT(m.theta, -M_PI);
      ++gt_seq;
    } else if (ev.channel == "ODOMETRY") {
      const auto m = decode<vslam::odometry_t>(ev);
      const BasePose p = odometryBase(0.02 * odo_seq);
      EXPECT_EQ(m.utime, ev.timestamp);
      EXPECT_EQ(m.utime, kT0 + 5000 + odo_seq * 20000);
      EXPECT_EQ(m.seq, odo_seq);
      EXPECT_NEAR(m.x, p.x, 1e-7);
      EXPECT_NEAR(m.y, p.y, 1e-7);
      EXPECT_NEAR(m.theta, p.theta, 1e-7);
      EXPECT_NEAR(m.distance, odo_seq * 0.02 * std::hypot(0.4, 0.1), 1e-6);
      EXPECT_NEAR(m.rotation, odo_seq * 0.02 * 0.5, 1e-6);
      if (odo_seq > 0) {
        EXPECT_NEAR(m.omega, -0.5, 1e-4);
      }
      ++odo_seq;
    }
  }
  EXPECT_EQ(calib_n, 3);

  // The imported log evaluates: raw odometry against ground truth.
  const auto eval =
      runProgram("vslam-eval", {log_.string(), "--odom-channel", "ODOMETRY", "--align", "se2"});
  EXPECT_EQ(eval.exit_code, 0) << eval.output;
  EXPECT_TRUE(contains(eval.output, "ATE pairs")) << eval.output;
}

TEST_F(Import, ColourResizeBgr8AndRescaledIntrinsics) {
  writeDataset(data_, true);
  auto args = baseArgs();
  for (const char* a :
       {"--encoding", "bgr8", "--resize", "32x24", "--camera", "left", "--frame-rate", "30"}) {
    args.push_back(a);
  }
  const auto r = runImport(args);
  ASSERT_EQ(r.code, 0) << r.err;
  int n = 0;
  for (const auto& ev : vslam::test::readLogEvents(log_)) {
    if (ev.channel == "CAM_LEFT_IMAGE") {
      const auto m = decode<vslam::image_t>(ev);
      EXPECT_EQ(m.camera, "left");
      EXPECT_EQ(m.encoding, vslam::image_t::ENCODING_BGR8);
      ASSERT_EQ(m.width, 32);
      ASSERT_EQ(m.height, 24);
      EXPECT_EQ(m.row_stride, 96);
      cv::Mat expected;
      cv::resize(colourImage(n), expected, {32, 24}, 0, 0, cv::INTER_AREA);
      const cv::Mat got(24, 32, CV_8UC3, const_cast<uint8_t*>(m.data.data()));
      EXPECT_EQ(cv::norm(got, expected, cv::NORM_INF), 0.0);
      ++n;
    } else if (ev.channel == "CAM_LEFT_CALIBRATION") {
      const auto m = decode<vslam::camera_calibration_t>(ev);
      EXPECT_EQ(m.image_channel, "CAM_LEFT_IMAGE");
      EXPECT_EQ(m.width, 32);
      EXPECT_EQ(m.height, 24);
      EXPECT_NEAR(m.fx, 25.0, 1e-12);
      EXPECT_NEAR(m.fy, 25.5, 1e-12);
      EXPECT_NEAR(m.cx, 15.5, 1e-12);  // (31.5 + 0.5) / 2 - 0.5
      EXPECT_NEAR(m.cy, 11.5, 1e-12);
      EXPECT_NEAR(m.frame_rate, 30.0, 1e-12);
    }
  }
  EXPECT_EQ(n, kImages);

  // Gray8 from colour is OpenCV's luminance; JPEG decodes to the image.
  fs::remove(log_);
  ASSERT_EQ(runImport(baseArgs()).code, 0);
  for (const auto& ev : vslam::test::readLogEvents(log_)) {
    if (ev.channel != "CAM_FORWARD_IMAGE") continue;
    const auto m = decode<vslam::image_t>(ev);
    cv::Mat expected;
    cv::cvtColor(colourImage(static_cast<int>(m.seq)), expected, cv::COLOR_BGR2GRAY);
    const cv::Mat got(kHeight, kWidth, CV_8UC1, const_cast<uint8_t*>(m.data.data()));
    EXPECT_EQ(cv::norm(got, expected, cv::NORM_INF), 0.0);
  }
  args = baseArgs();
  args.push_back("--encoding");
  args.push_back("jpeg");
  ASSERT_EQ(runImport(args).code, 0);
  for (const auto& ev : vslam::test::readLogEvents(log_)) {
    if (ev.channel != "CAM_FORWARD_IMAGE") continue;
    const auto m = decode<vslam::image_t>(ev);
    EXPECT_EQ(m.encoding, vslam::image_t::ENCODING_JPEG);
    EXPECT_EQ(m.row_stride, 0);
    const cv::Mat img = cv::imdecode(m.data, cv::IMREAD_COLOR);
    ASSERT_EQ(img.size(), cv::Size(kWidth, kHeight));
    // The same bytes as OpenCV's own encoding at the default quality 95.
    std::vector<uint8_t> expected;
    ASSERT_TRUE(cv::imencode(".jpg", colourImage(static_cast<int>(m.seq)), expected,
                             {cv::IMWRITE_JPEG_QUALITY, 95}));
    EXPECT_EQ(m.data, expected);
  }
}

TEST_F(Import, PlanarFromXzAndBaseFrameGroundTruth) {
  // Ground truth already of the base, in a world with y down: floor (x, z).
  writeDataset(data_, false);
  // x = s, z = 2 s, heading turning about -y by 0.1 s.
  std::string gt;
  for (int k = 0; k <= 30; ++k) {
    const double s = 0.1 * k;
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = Eigen::AngleAxisd(0.1 * s, -Eigen::Vector3d::UnitY()).matrix();
    T.translation() = Eigen::Vector3d(s, -0.05, 2 * s);
    gt += tumLine(kT0 + k * 100000, T);
  }
  writeText(data_ / "groundtruth.txt", gt);
  auto args = baseArgs();
  for (const char* a : {"--planar-from", "xz", "--gt-frame", "base"}) args.push_back(a);
  ASSERT_EQ(runImport(args).code, 0);
  int k = 0;
  for (const auto& ev : vslam::test::readLogEvents(log_)) {
    if (ev.channel != "GROUND_TRUTH") continue;
    const auto m = decode<vslam::ground_truth_pose_t>(ev);
    EXPECT_NEAR(m.x, 0.1 * k, 1e-7);
    EXPECT_NEAR(m.y, 0.2 * k, 1e-7);
    EXPECT_NEAR(m.z, 0.05, 1e-7);  // up is -y
    EXPECT_NEAR(m.theta, 0.01 * k, 1e-7);
    ++k;
  }
  EXPECT_EQ(k, 31);
}

TEST_F(Import, BadInputsAreNamed) {
  writeDataset(data_, false);
  auto expectError = [&](const std::string& what, const std::vector<std::string>& extra = {}) {
    auto args = baseArgs();
    args.insert(args.end(), extra.begin(), extra.end());
    const auto r = runImport(args);
    EXPECT_EQ(r.code, 1) << what;
    EXPECT_TRUE(contains(r.err, what)) << "expected '" << what << "' in: " << r.err;
    EXPECT_FALSE(fs::exists(log_)) << "partial output left behind for: " << what;
    EXPECT_FALSE(fs::exists(log_.string() + ".partial"));
  };
  const fs::path rgb = data_ / "rgb.txt";
  const std::string list = vslam::test::fileBytes(rgb);
  const std::string third = "rgb/" + stamp(imageUtime(2)) + ".png";

  // An unreadable image: the list's line (3 header lines, then images) and name.
  writeText(data_ / third, "not a png");
  expectError("rgb.txt:6: image '" + third + "': unreadable");
  // A missing one.
  fs::remove(data_ / third);
  expectError("rgb.txt:6: image '" + third + "': no such file");
  // One of another size.
  cv::imwrite((data_ / third).string(), cv::Mat(48, 60, CV_8UC1, cv::Scalar(7)));
  expectError("image '" + third + "' is 60x48, but the first");
  cv::imwrite((data_ / third).string(), grayImage(2));
  // A malformed list line.
  writeText(rgb, list + "12345.6\n");
  expectError("rgb.txt:10: expected 'timestamp filename'");
  writeText(rgb, list);
  // Missing list, ground truth; malformed ground truth.
  fs::rename(rgb, data_ / "rgb.bak");
  expectError("rgb.txt: no such file");
  fs::rename(data_ / "rgb.bak", rgb);
  const std::string gt = vslam::test::fileBytes(data_ / "groundtruth.txt");
  writeText(data_ / "groundtruth.txt", gt + "1305031105.0 1 2 3\n");
  expectError("groundtruth.txt:34: expected 8 fields");
  fs::remove(data_ / "groundtruth.txt");
  expectError("groundtruth.txt: no such file");
  writeText(data_ / "groundtruth.txt", gt);
  expectError("odometry.txt: no such file",
              {"--odometry", (data_ / "nope" / "odometry.txt").string()});
  // A calibration for another size.
  writeCalibration(data_ / "calib.yml", 640, 480);
  expectError("is for 640x480 images, but the images are 64x48");
  writeCalibration(data_ / "calib.yml", kWidth, kHeight);
  // And the folder itself.
  auto r =
      runImport({(dir_ / "absent").string(), "--calibration", "c.yml", "--out", log_.string()});
  EXPECT_EQ(r.code, 1);
  EXPECT_TRUE(contains(r.err, "absent: no such folder")) << r.err;
  // Everything restored: it imports.
  EXPECT_EQ(runImport(baseArgs()).code, 0);
}

// A stack config whose robot file has one camera 'front' calibrated for
// width x height, on its own channels.
fs::path writeStackConfig(const fs::path& dir, int width, int height) {
  writeCalibration(dir / "robot_calib.yml", width, height);
  std::string channels = "channels:\n";
  for (const auto& f : vslam::config::ChannelNames::fields()) {
    std::string upper = f.key;
    for (auto& c : upper) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
    channels += std::string("  ") + f.key + ": " + upper + "\n";
  }
  writeText(dir / "robot.yaml",
            "name: one_camera_test\n"
            "cameras:\n"
            "  - name: front\n"
            "    calibration: robot_calib.yml\n"
            "    frame_rate_hz: 2\n"
            "    position_m: [0.1, 0.0, 0.3]\n"
            "    orientation_deg: {yaw: 0, pitch: 0, roll: 0}\n"
            "    image_channel: FRONT_IMAGE\n"
            "    calibration_channel: FRONT_CALIBRATION\n" +
                channels);
  writeText(dir / "stack.yaml", "robot: robot.yaml\nprocesses: {}\n");
  return dir / "stack.yaml";
}

TEST_F(Import, ImagesOfAnotherSizeThanTheRobotFileAreRefused) {
  writeDataset(data_, false);
  // Without a stack config the size cannot be checked: said, not silent.
  auto r = runImport(baseArgs());
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(contains(r.err, "not checked against a robot file")) << r.err;
  fs::remove(log_);

  // The robot's camera is 32x24, the images 64x48: refused, both sizes named.
  const fs::path stack = writeStackConfig(dir_, kWidth / 2, kHeight / 2);
  auto args = baseArgs();
  for (const char* a : {"--config", "", "--camera", "front"}) {
    args.push_back(*a ? a : stack.string());
  }
  r = runImport(args);
  EXPECT_EQ(r.code, 1) << r.err;
  EXPECT_TRUE(contains(r.err, "the images are 64x48, but camera 'front' in")) << r.err;
  EXPECT_TRUE(contains(r.err, "robot.yaml is 32x24")) << r.err;
  EXPECT_TRUE(contains(r.err, "--resize 32x24")) << r.err;
  EXPECT_FALSE(fs::exists(log_));
  EXPECT_FALSE(fs::exists(log_.string() + ".partial"));

  // Resized to another size than the robot's: refused as well.
  auto resized = args;
  resized.insert(resized.end(), {"--resize", "40x30"});
  r = runImport(resized);
  EXPECT_EQ(r.code, 1) << r.err;
  EXPECT_TRUE(contains(r.err, "64x48 resized to 40x30, but camera 'front'")) << r.err;

  // Resized to the robot's size: imported on the robot file's channels, with
  // the rescaled intrinsics.
  resized = args;
  resized.insert(resized.end(), {"--resize", "32x24"});
  r = runImport(resized);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_FALSE(contains(r.err, "not checked")) << r.err;
  int images = 0, calibrations = 0;
  for (const auto& ev : vslam::test::readLogEvents(log_)) {
    EXPECT_NE(ev.channel, "CAM_FRONT_IMAGE");
    if (ev.channel == "FRONT_IMAGE") {
      const auto m = decode<vslam::image_t>(ev);
      EXPECT_EQ(m.width, kWidth / 2);
      EXPECT_EQ(m.height, kHeight / 2);
      ++images;
    } else if (ev.channel == "FRONT_CALIBRATION") {
      const auto m = decode<vslam::camera_calibration_t>(ev);
      EXPECT_EQ(m.width, kWidth / 2);
      EXPECT_DOUBLE_EQ(m.fx, 25.0);
      ++calibrations;
    }
  }
  EXPECT_EQ(images, kImages);
  EXPECT_GT(calibrations, 0);

  // A camera the robot file does not have, and a stack config that is not
  // there: bad command line / configuration, exit 2.
  auto other = baseArgs();
  other.insert(other.end(), {"--config", stack.string(), "--camera", "forward"});
  r = runImport(other);
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_TRUE(contains(r.err, "--camera forward: no such camera")) << r.err;
  EXPECT_TRUE(contains(r.err, "cameras: front")) << r.err;
  other = baseArgs();
  other.insert(other.end(), {"--config", (dir_ / "absent.yaml").string()});
  r = runImport(other);
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_TRUE(contains(r.err, "absent.yaml")) << r.err;

  // The program: exit 1 with the message.
  const auto p = runProgram("vslam-import", args);
  EXPECT_EQ(p.exit_code, 1) << p.output;
  EXPECT_TRUE(contains(p.output, "is 32x24")) << p.output;
}

TEST_F(Import, OptionValuesMayFollowAnEqualsSign) {
  writeDataset(data_, false);
  const auto r = runImport({data_.string(), "--calibration=" + (data_ / "calib.yml").string(),
                            "--out=" + log_.string(), "--encoding=jpeg", "--resize=32x24"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(contains(r.out, "(jpeg, 32x24)")) << r.out;
  EXPECT_EQ(runImport({data_.string(), "--calibration=" + (data_ / "calib.yml").string(),
                       "--out=" + log_.string(), "--resize=32"})
                .code,
            2);
}

TEST_F(Import, ProgramExitCodes) {
  writeDataset(data_, false);
  auto r = runProgram("vslam-import", {data_.string(), "--out", log_.string()});
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_TRUE(contains(r.output, "--calibration FILE is required")) << r.output;
  for (const std::vector<std::string>& extra : {std::vector<std::string>{"--encoding", "png"},
                                                {"--resize", "64"},
                                                {"--planar-from", "yz"},
                                                {"--gt-frame", "world"},
                                                {"--camera-position", "1,2"},
                                                {"--bogus"}}) {
    auto args = baseArgs();
    args.insert(args.end(), extra.begin(), extra.end());
    r = runProgram("vslam-import", args);
    EXPECT_EQ(r.exit_code, 2) << extra[0] << ": " << r.output;
  }
  r = runProgram("vslam-import", baseArgs());
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(fs::exists(log_));
  writeText(data_ / "rgb.txt", "# nothing\n");
  r = runProgram("vslam-import", baseArgs());
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_TRUE(contains(r.output, "rgb.txt: lists no images")) << r.output;
}
