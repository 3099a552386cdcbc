#pragma once
// vslam-odometry-bridge: a robot base's odometry, as lines on stdin, a
// serial port or a localhost UDP socket, published as vslam.odometry_t on
// the robot file's odometry channel (docs/odometry.md). The parsing, checks
// and wheel integration are odometry_bridge::LineBridge; this stage reads
// the source on its own thread, publishes, and reports health.
//
// A driver, not a pipeline stage: registered in driverStages(), so
// vslam-replay (where the log holds the odometry) never starts it.

#include <atomic>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <thread>

#include "bus/stage.hpp"
#include "bus/stage_registry.hpp"
#include "odometry_bridge/line_bridge.hpp"
#include "odometry_bridge/line_source.hpp"
#include "util/log.hpp"

namespace vslam::stages {

struct OdometryBridgeParams {
  odometry_bridge::BridgeParams bridge;
  odometry_bridge::SourceParams source;
  std::string odometry_channel;
  double line_timeout_s = 1.0;   // health warns when no line arrived for this long
  double reopen_period_s = 1.0;  // a serial device that went away is reopened this often

  // The keys of the block, declared once (config/param_table.hpp).
  static const config::ParamTable<OdometryBridgeParams>& table();
  static OdometryBridgeParams load(const config::ConfigNode& node,
                                   const config::RobotConfig& robot);
};

class OdometryBridgeStage final : public bus::Stage {
 public:
  // Opens the source; throws config::ConfigError naming the key of the
  // device or port that cannot be opened.
  OdometryBridgeStage(OdometryBridgeParams params, const config::ConfigNode& node);
  ~OdometryBridgeStage() override;
  void start(bus::StageContext& ctx) override;
  void collectHealth(bus::HealthReport& report) override;
  void stop() override;
  std::vector<std::string> outputChannels() const override { return {params_.odometry_channel}; }

 private:
  void readLoop();
  void handleLine(const std::string& line);
  // Waits up to `seconds` or until stop(); false if stopping.
  bool waitOrStop(double seconds);

  OdometryBridgeParams params_;
  bus::StageContext* ctx_ = nullptr;
  std::unique_ptr<odometry_bridge::LineSource> source_;
  std::thread reader_;
  std::mutex mutex_;  // bridge_, source_open_, period counters
  std::condition_variable stop_cv_;
  bool stopping_ = false;
  odometry_bridge::LineBridge bridge_;
  bool source_open_ = true;
  int64_t period_rejected_ = 0;
  log::RateLimitedWarnings<odometry_bridge::kNumRejections> warnings_{kMicrosPerSecond};
};

void registerOdometryBridge(bus::StageRegistry& registry);

}  // namespace vslam::stages
