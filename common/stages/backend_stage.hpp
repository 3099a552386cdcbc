#pragma once
// vslam-backend: the vSLAM pre-filter (paper section 5) and SLAM back-end
// (section 6) over the library common/backend (no LCM there; this is the
// adapter).
//
// Inputs: ODOMETRY (cumulative pose; differences drive the motion model) and
// VISUAL_MEASUREMENT from any number of front-ends (cameras), all fused in one
// filter. Outputs:
//   VISUAL_MEASUREMENT_FILTERED  every measurement again, status = the pre-filter's verdict
//   POSE_ESTIMATE                per odometry reading: particle mean, covariance, ESS, kidnapped
//   MAP                          at map_rate_hz (robot time): the best particle's landmark poses
//   PARTICLES                    at particles_rate_hz: the particle set with weights and kinds
//   HEALTH                       accepted/rejected counts by reason, filter figures
// Bad input (non-finite odometry or measurements, negative landmark ids,
// measurements outside the odometry history) is counted and logged at most
// once per reason every few seconds; the stage keeps running.

#include <array>
#include <atomic>
#include <filesystem>
#include <optional>
#include <vslam/landmark_update_t.hpp>
#include <vslam/odometry_t.hpp>
#include <vslam/view_jump_t.hpp>
#include <vslam/visual_measurement_t.hpp>

#include "backend/backend.hpp"
#include "bus/input_watchdog.hpp"
#include "bus/repeat_filter.hpp"
#include "bus/stage.hpp"
#include "bus/stage_registry.hpp"
#include "landmark_db/landmark_store.hpp"
#include "util/log.hpp"

namespace vslam::stages {

struct BackendStageParams {
  backend::BackendParams backend;
  std::string odometry_channel;
  std::string measurement_channel;
  std::string view_jump_channel;          // front-ends' view jumps, for the kidnap test
  std::string landmark_update_channel;    // creation times for map correction
  std::string landmark_proposal_channel;  // ...from front-ends without a landmark DB
  std::string filtered_channel;
  std::string pose_channel;
  std::string map_channel;
  std::string particles_channel;
  double map_rate_hz = 1.0;        // MAP messages per second of robot time; 0: none
  double particles_rate_hz = 2.0;  // PARTICLES messages per second of robot time; 0: none
  // Odometry quieter than this (stage clock) is logged once and raises
  // health to WARN: the published pose no longer moves with the robot.
  double odometry_timeout_s = 2.0;
  std::string database_id;  // map_t.database_id ("" until a landmark DB names one)
  // Localization in a known map: the landmark map file of an earlier run
  // (vslam-landmark-db's map_file), read once at start-up. Its landmarks
  // with a back-end pose (pose source "map") start in every particle's map
  // with this standard deviation; the particles start at the map origin
  // (the earlier run's start pose). Empty: start with an empty map.
  std::filesystem::path map_prior_file;
  // `map_prior_file: landmark_db`: the map file of this stack's landmark DB,
  // read if it exists (a restarted back-end, or a new session in a mapped
  // home, continues in the DB's frame instead of starting a new one).
  bool map_prior_from_landmark_db = false;
  double map_prior_sigma_xy_m = 0.05;
  double map_prior_sigma_theta_rad = 1.0 * M_PI / 180;
  // Where the robot starts in the map prior: at its origin (the pose of the
  // run that built it), or unknown, relocalized globally from the first
  // measurements (all dual particles until confirmed).
  bool map_prior_unknown_start = false;
  // A map file that holds the robot's last pose (the landmark DB saves the
  // back-end's estimates) saved at most this long before the first
  // odometry, robot time: the back-end resumes there instead (a restart
  // after a crash, its odometry frame unchanged). 0: never.
  double map_prior_resume_max_gap_s = 30.0;

  // The keys of the block, declared once (config/param_table.hpp).
  static const config::ParamTable<BackendStageParams>& table();
  // `prefilter`: the stack's (loadPrefilter in stages/prefilter_config.hpp).
  static BackendStageParams load(const config::ConfigNode& node, const config::RobotConfig& robot,
                                 const backend::PrefilterParams& prefilter);
};

class BackendStage final : public bus::Stage {
 public:
  explicit BackendStage(BackendStageParams params);
  void start(bus::StageContext& ctx) override;
  void collectHealth(bus::HealthReport& report) override;
  std::vector<std::string> outputChannels() const override;

  const backend::Backend& backend() const { return backend_; }
  backend::Backend& backend() { return backend_; }  // for tests and tools that drive it directly
  // Landmarks loaded from map_prior_file (0 without one).
  size_t priorLandmarks() const { return prior_landmarks_; }

 private:
  void onOdometry(const vslam::odometry_t& msg);
  void onMeasurement(const vslam::visual_measurement_t& msg);
  void onViewJump(const vslam::view_jump_t& msg);
  void onLandmarkUpdate(const vslam::landmark_update_t& msg);
  void publishPose(const vslam::odometry_t& msg);
  // Logs the estimate at every 100 new pairs (called with the health, once a period).
  void logOdometryCalibration(const backend::OdometryNoiseEstimate& n);
  void publishMap(Utime utime);
  void publishParticles(Utime utime);
  // At most one log line per reason per 5 s of stage time.
  enum LogReason { kLogOdometry, kLogMeasurement, kLogLandmark, kLogTiming, kLogKidnap, kNumLog };
  template <class... Args>
  void logLimited(LogReason reason, const Args&... args);

  void loadMapPrior();
  // The map prior's standard deviations as a covariance (x, y, θ).
  Eigen::Matrix3d mapPriorCovariance() const;
  // At the first odometry reading with a map prior: resume at the map file's
  // robot pose if it is recent enough, else start as map_prior_start says.
  void chooseStart(const vslam::odometry_t& first);

  BackendStageParams params_;
  backend::Backend backend_;
  size_t prior_landmarks_ = 0;
  // The map prior's robot pose, until the first odometry reading judges it.
  std::optional<landmark_db::RobotPoseRecord> saved_robot_pose_;
  bool resumed_ = false;  // started at saved_robot_pose_ (health)
  bus::StageContext* ctx_ = nullptr;
  int64_t pose_seq_ = 0, map_seq_ = 0, particles_seq_ = 0;
  Utime next_map_ = 0, next_particles_ = 0;
  std::unique_ptr<bus::InputWatchdog> odometry_watchdog_;  // from start()
  bus::RepeatFilter repeated_measurements_;                // one fused twice would count twice
  log::RateLimitedWarnings<kNumLog> warnings_{5 * kMicrosPerSecond};
  // Period figures for health.
  int64_t period_updates_ = 0;
  double period_update_ms_ = 0;
  double period_max_update_ms_ = 0;
  int calibration_logged_pairs_ = 0;
  int64_t view_jumps_ = 0;  // front-ends' view jumps received
};

void registerBackend(bus::StageRegistry& registry);

}  // namespace vslam::stages
