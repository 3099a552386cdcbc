#pragma once
// The robot description shared by every process: cameras (intrinsics in
// OpenCV's calibration file format, extrinsics relative to the robot base)
// and the names of the LCM channels the stack uses.

#include <Eigen/Geometry>
#include <filesystem>
#include <iosfwd>
#include <string>
#include <vector>

#include "config/config_node.hpp"
#include "util/alternation.hpp"

namespace vslam::config {

// Pinhole intrinsics as in OpenCV's calibration file format.
struct CameraIntrinsics {
  int width = 0;                          // pixels
  int height = 0;                         // pixels
  double fx = 0, fy = 0, cx = 0, cy = 0;  // pixels
  std::vector<double> distortion;         // OpenCV order k1 k2 p1 p2 [k3 ...]
};

// Reads image_width, image_height, camera_matrix and distortion_coefficients
// from an OpenCV calibration file (as written by OpenCV's calibration
// sample) and validates them; ConfigError names the file and the field.
CameraIntrinsics readOpenCvCalibration(const std::filesystem::path& file);

// The heading of a camera's optical axis (OpenCV's camera z) in the robot
// frame: radians about the robot's z from its x (forward).
double opticalAxisHeading(const Eigen::Matrix3d& robot_R_camera);

struct CameraConfig {
  std::string name;  // e.g. "forward"
  std::filesystem::path calibration_file;
  int width = 0;                          // pixels
  int height = 0;                         // pixels
  double fx = 0, fy = 0, cx = 0, cy = 0;  // pixels
  std::vector<double> distortion;         // OpenCV order k1 k2 p1 p2 [k3 ...]
  double frame_rate_hz = 0;
  // Taking turns with other cameras (`alternate:`): the simulator renders
  // this camera only in its slot of slots / frame_rate_hz (util/alternation.hpp).
  Alternation alternate;
  // Camera frame (OpenCV: x right, y down, z optical axis) in the robot base
  // frame (x forward, y left, z up).
  Eigen::Isometry3d robot_T_camera = Eigen::Isometry3d::Identity();
  std::string image_channel;        // vslam.image_t
  std::string calibration_channel;  // vslam.camera_calibration_t
};

// Every channel the stack publishes or subscribes, besides the per-camera ones.
struct ChannelNames {
  std::string odometry;                     // vslam.odometry_t
  std::string ground_truth;                 // vslam.ground_truth_pose_t
  std::string health;                       // vslam.health_t
  std::string pose_estimate;                // vslam.pose_estimate_t (back-end)
  std::string pose_odometry;                // vslam.pose_estimate_t (odometry-only baseline)
  std::string visual_measurement;           // vslam.visual_measurement_t (front-ends)
  std::string visual_measurement_filtered;  // vslam.visual_measurement_t (pre-filter verdicts)
  std::string landmark_proposal;            // vslam.landmark_update_t (front-ends -> DB)
  std::string landmark_update;              // vslam.landmark_update_t (DB)
  std::string landmark_summary;             // vslam.landmark_summary_t (DB)
  std::string landmark_request;             // vslam.landmark_request_t (-> DB)
  std::string map;                          // vslam.map_t (back-end)
  std::string particles;                    // vslam.particle_set_t (back-end)
  std::string appearance_hypotheses;        // vslam.appearance_hypotheses_t
  std::string appearance_map;               // vslam.appearance_map_t
  std::string appearance_event;             // vslam.appearance_event_t
  std::string view_jump;                    // vslam.view_jump_t (front-ends -> back-end)

  // Every field with its key in the robot file's `channels:` block.
  struct Field {
    const char* key;
    std::string ChannelNames::*member;
  };
  static const std::vector<Field>& fields();
};

struct RobotConfig {
  std::string name;
  std::filesystem::path file;
  std::vector<CameraConfig> cameras;
  ChannelNames channels;

  // Reads and validates a robot file; unknown keys are errors.
  static RobotConfig load(const ConfigNode& node);
  static RobotConfig loadFile(const std::filesystem::path& file);
  const CameraConfig& camera(const std::string& name) const;  // throws std::out_of_range
  void print(std::ostream& os) const;
};

// An `alternate: {slot: K, slots: N}` block (util/alternation.hpp) for
// cameras sharing `rate_hz`; ConfigError names `key`.slot or `key`.slots.
// Absent: no alternation.
Alternation readAlternation(const ConfigNode& node, const std::string& key, double rate_hz);

// Camera orientation given as yaw/pitch/roll of the optical axis relative to
// a camera looking straight forward along the robot's x axis, level, image
// upright (yaw 180 = backward camera; pitch > 0 tilts it up).
Eigen::Matrix3d robotRotationCamera(double yaw_rad, double pitch_rad, double roll_rad);

}  // namespace vslam::config
