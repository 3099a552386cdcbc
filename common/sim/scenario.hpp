#pragma once
// A simulation scenario (config/scenarios/*.yaml): the world, how the robot
// moves, how its odometry errs, what the cameras add, and scripted
// disturbances. Loaded with the same validating reader as every config, so
// a bad key names the file and line.

#include <Eigen/Core>
#include <filesystem>
#include <string>
#include <vector>

#include "config/config_node.hpp"
#include "odometry/pose2.hpp"

namespace vslam::sim {

enum class MotionMode {
  kWaypoints,   // drive a closed list of waypoints, `laps` times
  kRandom,      // wander, turning away from walls and furniture
  kActions,     // discrete actions (forward / turn) with multiplicative action error
  kTrajectory,  // follow a TUM trajectory file (ground truth), optionally with its odometry
};

struct MotionParams {
  MotionMode mode = MotionMode::kWaypoints;
  Pose2 start;                                 // world frame; theta radians
  bool has_start = false;                      // otherwise the world file's `start`
  double speed_mps = 0.3;                      // forward speed when driving
  double turn_rate_rps = 45.0 * M_PI / 180.0;  // rotation speed when turning in place, rad/s
  // waypoints
  std::vector<Eigen::Vector2d> waypoints;
  std::string route;  // or a named route of the world file
  int laps = 1;
  // random
  double lookahead_m = 0.5;     // obstacle look-ahead while driving
  double robot_radius_m = 0.2;  // clearance kept from walls and furniture
  // actions: tokens "F" (forward one action length), "L"/"R" (turn left/right),
  // each optionally with a repeat count ("F9 L F6 R ...").
  std::string actions;
  double action_length_m = 1.0;
  double action_turn_rad = 90.0 * M_PI / 180.0;
  double action_error = 0.03;   // relative standard deviation of each executed action
  double action_pause_s = 0.5;  // robot stands still after each action (snapshot time)
  // trajectory
  std::filesystem::path trajectory_file;  // TUM: t x y z qx qy qz qw
  std::filesystem::path odometry_file;  // optional TUM odometry used instead of simulated odometry
};

struct SlipEvent {
  double at_s = 0;
  double duration_s = 0;
  double translation_factor = 1.0;  // odometry reports this fraction of the true translation
  double rotation_factor = 1.0;     // and of the true rotation
};

struct OdometryParams {
  double rate_hz = 50;
  double sigma_translation = 0.02;  // sigma_T, m / sqrt(m) (common/odometry/motion_model.hpp)
  double sigma_rotation = 0.02;     // sigma_R, rad / sqrt(m or rad)
  // Systematic errors of real wheels, applied before the noise: odometry
  // reports (1 + scale_bias) x the true translation (a wrong wheel
  // diameter), and heading_bias rad of extra rotation per metre driven
  // (unequal wheel diameters make the reported path curve).
  double scale_bias = 0;
  double heading_bias = 0;  // rad / m
  std::vector<SlipEvent> slips;
};

struct CameraParams {
  std::string encoding = "gray8";  // gray8 | bgr8 | jpeg
  int jpeg_quality = 90;
  double noise_sigma = 1.5;  // grey levels
  bool motion_blur = true;
  int blur_samples = 3;
  double exposure_time_s = 0.012;  // shutter open time, for motion blur
};

struct KidnapEvent {
  double at_s = 0;
  Pose2 to;  // world frame
};

struct LightEvent {
  double at_s = 0;
  double duration_s = 0;  // 0 = until the end
  double exposure = 1.0;  // multiplies the world's exposure
};

struct PeopleParams {
  int count = 0;
  double speed_mps = 0.6;
  double height_m = 1.7;
  double width_m = 0.45;
  double depth_m = 0.3;
  std::string texture = "skimage:astronaut.png";
};

struct Scenario {
  std::string name;
  std::filesystem::path file;
  std::filesystem::path world_file;
  uint64_t seed = 1;
  double duration_s = 0;         // 0 = until the motion ends
  double max_duration_s = 3600;  // safety bound for random motion
  MotionParams motion;
  OdometryParams odometry;
  CameraParams cameras;
  std::vector<KidnapEvent> kidnaps;
  std::vector<LightEvent> lights;
  PeopleParams people;

  static Scenario load(const config::ConfigNode& node);
  // NAME (config/scenarios/NAME.yaml under `scenario_dir`) or a path to a file.
  static Scenario loadByName(const std::string& name_or_path,
                             const std::filesystem::path& scenario_dir);
};

// Parses "F9 L F6 R F" into unit actions: +1 forward, 'L', 'R'. Throws
// std::invalid_argument naming the bad token.
std::vector<char> parseActions(const std::string& text);

}  // namespace vslam::sim
