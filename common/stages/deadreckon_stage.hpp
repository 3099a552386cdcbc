#pragma once
// vslam-deadreckon: the odometry-only baseline. Integrates wheel odometry with
// the back-end's motion model and publishes the pose with its growing
// covariance, so evaluations can compare vSLAM against odometry alone (the
// green paths of the paper's Figs. 7 and 9) on the same bus.

#include <memory>
#include <vslam/odometry_t.hpp>

#include "bus/input_watchdog.hpp"
#include "bus/stage.hpp"
#include "bus/stage_registry.hpp"
#include "odometry/motion_model.hpp"

namespace vslam::stages {

struct DeadReckonParams {
  MotionNoise noise;
  std::string odometry_channel;
  std::string pose_channel;
  double max_step_m = 1.0;  // larger jumps between readings are faults, not motion
  double max_step_deg = 90.0;
  double odometry_timeout_s = 2.0;  // quieter odometry is logged once and raises health to WARN

  // The keys of the block, declared once (config/param_table.hpp).
  static const config::ParamTable<DeadReckonParams>& table();
  static DeadReckonParams load(const config::ConfigNode& node, const config::RobotConfig& robot);
};

class DeadReckonStage final : public bus::Stage {
 public:
  explicit DeadReckonStage(DeadReckonParams params);
  void start(bus::StageContext& ctx) override;
  void collectHealth(bus::HealthReport& report) override;
  std::vector<std::string> outputChannels() const override { return {params_.pose_channel}; }

 private:
  void onOdometry(const vslam::odometry_t& msg);

  DeadReckonParams params_;
  bus::StageContext* ctx_ = nullptr;
  OdometryIncrements increments_;
  PoseWithCovariance estimate_;
  int64_t seq_ = 0;
  int64_t ignored_ = 0;
  int64_t period_steps_ = 0;
  double distance_m_ = 0;
  std::unique_ptr<bus::InputWatchdog> odometry_watchdog_;  // from start()
};

void registerDeadReckon(bus::StageRegistry& registry);

}  // namespace vslam::stages
