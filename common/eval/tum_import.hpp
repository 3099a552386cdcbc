#pragma once
// Converts a TUM RGB-D-layout folder into an LCM log on the stack's channels:
//   rgb.txt          "timestamp filename" per image (PNG/JPEG, colour or gray)
//   groundtruth.txt  TUM trajectory of the colour camera  -> GROUND_TRUTH
//   [odometry file]  TUM trajectory of the robot base     -> ODOMETRY
// plus the camera's calibration (an OpenCV calibration file) at 1 Hz. Event
// timestamps are the data timestamps in microseconds, events in time order
// (at equal times: calibration, ground truth, odometry, image).

#include <Eigen/Core>
#include <filesystem>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "config/robot_config.hpp"
#include "eval/planar.hpp"

namespace vslam::eval {

enum class ImageEncoding { kGray8, kBgr8, kJpeg };
std::optional<ImageEncoding> parseImageEncoding(const std::string& word);
std::string toString(ImageEncoding encoding);

struct ImportOptions {
  std::filesystem::path dataset;                     // the folder
  std::filesystem::path output;                      // log to write (replaced)
  std::filesystem::path calibration;                 // OpenCV calibration file, required
  std::optional<std::filesystem::path> rgb_list;     // default dataset/rgb.txt
  std::optional<std::filesystem::path> groundtruth;  // default dataset/groundtruth.txt
  std::optional<std::filesystem::path> odometry;     // TUM file of robot base poses, z up

  std::string camera = "forward";
  std::string image_channel;        // empty: CAM_<CAMERA>_IMAGE
  std::string calibration_channel;  // empty: CAM_<CAMERA>_CALIBRATION
  std::string ground_truth_channel = "GROUND_TRUTH";
  std::string odometry_channel = "ODOMETRY";

  ImageEncoding encoding = ImageEncoding::kGray8;
  int jpeg_quality = 95;
  std::optional<cv::Size> resize;
  double frame_rate_hz = 0;  // 0: 1 / median interval of rgb.txt
  double calibration_period_s = 1.0;

  // Ground truth: floor axes of its world frame, and whether its poses are
  // of the camera (TUM RGB-D) or already of the robot base.
  FloorAxes floor = FloorAxes::kXY;
  bool groundtruth_is_camera = true;
  // Extrinsics: camera origin in the robot frame (m) and orientation as in
  // the robot file (degrees; 0,0,0 = level, looking along the robot's +x).
  Eigen::Vector3d camera_position_m = Eigen::Vector3d::Zero();
  Eigen::Vector3d camera_yaw_pitch_roll_deg = Eigen::Vector3d::Zero();

  // The camera of the robot file the log is for: the written image size
  // must be its size (front-ends drop frames of another size), else
  // DataError naming both. Unset: no check.
  std::optional<config::CameraConfig> robot_camera;
  std::filesystem::path robot_file;  // where robot_camera comes from, for messages
};

struct ImportStats {
  std::size_t images = 0, ground_truth = 0, odometry = 0, calibration = 0;
  cv::Size source_size, image_size;  // as read, as written
  double frame_rate_hz = 0;
  int64_t first_utime = 0, last_utime = 0;
  std::string image_channel, calibration_channel;
};

// Throws DataError naming the file (and line) for missing or malformed
// inputs, unreadable images and images of inconsistent size; UsageError for
// inconsistent options. On failure no output file is left behind.
ImportStats importTumDataset(const ImportOptions& options);

// CAM_<NAME upper-cased>_IMAGE / _CALIBRATION.
std::string defaultImageChannel(const std::string& camera);
std::string defaultCalibrationChannel(const std::string& camera);

}  // namespace vslam::eval
