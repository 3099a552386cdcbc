#pragma once
// vslam-appearance: appearance-based topological SLAM (Lee & Sowmya) beside
// the metric vSLAM stack, on the same camera and odometry channels. The
// algorithm lives in common/appearance (no LCM); this stage
//   - cuts odometry into actions (a move of action_distance_m, a turn of
//     action_turn_deg, or a move ended by the robot stopping),
//   - after each action takes a snapshot: the next image of every camera,
//     reduced to a gradient-orientation histogram,
//   - runs one step of the path-hypothesis tree, and publishes the
//     hypotheses (APPEARANCE_HYPOTHESES, every step), events
//     (APPEARANCE_EVENT: EVENT_RELOCALIZED when the most believed hypothesis
//     becomes a revisit after a new state, or jumps to another branch and
//     another state; EVENT_NEW_STATE when it becomes a new state after a
//     revisit; EVENT_LOST) and the map of the most believed hypothesis
//     (APPEARANCE_MAP, every map_period_s and after a step that follows a
//     load);
//   - loads the map from map_file at start and saves it there at shutdown
//     (and every map_save_period_s), if configured.
// See docs/appearance.md.

#include <optional>
#include <vslam/appearance_hypotheses_t.hpp>
#include <vslam/image_t.hpp>
#include <vslam/odometry_t.hpp>

#include "appearance/action_detector.hpp"
#include "appearance/gradient_histogram.hpp"
#include "appearance/path_hypotheses.hpp"
#include "bus/input_watchdog.hpp"
#include "bus/stage.hpp"
#include "bus/stage_registry.hpp"

namespace vslam::stages {

struct AppearanceParams {
  std::vector<std::string> camera_names;      // of the robot file, as the config lists them
  std::vector<config::CameraConfig> cameras;  // one histogram per camera, in this order
  std::string odometry_channel;
  std::string hypotheses_channel;
  std::string map_channel;
  std::string event_channel;
  appearance::ActionParams action;
  double snapshot_timeout_s = 1.0;  // then step with the cameras that gave an image
  double input_timeout_s = 2.0;     // quieter images or odometry: logged once, health WARN
  appearance::HistogramParams histogram;
  appearance::SlamParams slam;
  // Revisits and seeds with the robot turned around, through cameras that
  // face each other's way (appearance::turnedCameras of the robot file).
  bool turned_revisits = true;
  appearance::ActionErrorModel action_error;
  double map_period_s = 5.0;
  std::filesystem::path map_file;  // empty: no persistence
  bool map_load = false;
  bool map_save = false;
  double map_save_period_s = 10.0;  // 0: only at shutdown

  // The keys of the block, declared once (config/param_table.hpp).
  static const config::ParamTable<AppearanceParams>& table();
  static AppearanceParams load(const config::ConfigNode& node, const config::RobotConfig& robot);
};

class AppearanceStage final : public bus::Stage {
 public:
  explicit AppearanceStage(AppearanceParams params);
  void start(bus::StageContext& ctx) override;
  void onTimer(Utime now) override;
  void stop() override;
  void collectHealth(bus::HealthReport& report) override;
  std::vector<std::string> outputChannels() const override {
    return {params_.hypotheses_channel, params_.map_channel, params_.event_channel};
  }

  const appearance::AppearanceSlam& slam() const { return slam_; }

 private:
  struct Pending {
    Utime utime = 0;  // odometry time the action ended
    std::vector<appearance::Histogram> histograms;
    std::vector<Utime> image_utime;
    int collected = 0;
  };

  void onOdometry(const vslam::odometry_t& msg);
  void onImage(size_t camera, const vslam::image_t& msg);
  bool validImage(const config::CameraConfig& camera, const vslam::image_t& msg);
  bool toGray(const config::CameraConfig& camera, const vslam::image_t& msg);  // a valid image
  void takeSnapshot();
  void publishStep(const appearance::StepResult& r, Utime utime, double seconds);
  void publishMap(Utime now);
  void saveMap(bool periodic = false);  // periodic: logged at debug level
  std::vector<std::string> cameraNames() const;

  AppearanceParams params_;
  bus::StageContext* ctx_ = nullptr;
  // One per camera, then odometry (from start()).
  std::vector<std::unique_ptr<bus::InputWatchdog>> watchdogs_;
  appearance::AppearanceSlam slam_;
  appearance::ActionDetector detector_;
  std::optional<Pending> pending_;
  bool have_odometry_ = false;
  Utime odometry_utime_ = 0;
  Pose2 odometry_;
  Pose2 reference_;  // odometry pose of the last snapshot
  cv::Mat gray_;
  std::optional<appearance::HypothesisInfo> last_best_;
  int64_t map_seq_ = 0;
  int64_t map_published_step_ = -1;
  Utime last_map_publish_ = 0;
  Utime last_map_save_ = 0;
  int64_t saved_steps_ = -1;  // steps_total_ at the last save: an unchanged map is not rewritten
  bool map_dirty_ = false;
  bool loaded_map_ = false;
  // Health, per period.
  int64_t steps_ = 0, relocalizations_ = 0, partial_snapshots_ = 0, steps_total_ = 0;
  double step_ms_sum_ = 0, step_ms_max_ = 0;
};

void registerAppearance(bus::StageRegistry& registry);

}  // namespace vslam::stages
