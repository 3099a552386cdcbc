#pragma once
// vslam-camera: one camera of the robot file as a driver. Captures from a
// V4L2 device, a GStreamer pipeline, a video file or an image folder
// (common/capture), publishes vslam.image_t on the camera's image channel and
// vslam.camera_calibration_t (the robot file's) on its calibration channel at
// 1 Hz. A live source only: vslam-replay never runs it (the log is the camera).

#include <atomic>
#include <memory>
#include <thread>

#include "bus/stage.hpp"
#include "bus/stage_registry.hpp"
#include "capture/camera.hpp"
#include "capture/image_encoding.hpp"

namespace vslam::stages {

struct CameraStageParams {
  std::string camera_name;      // the robot file's camera...
  config::CameraConfig camera;  // ...as the robot file describes it
  std::string source_text;      // as configured, e.g. "v4l2:/dev/video0"...
  capture::SourceSpec source;   // ...parsed
  capture::CameraParams capture;
  capture::PixelEncoding encoding = capture::PixelEncoding::kGray8;
  int jpeg_quality = 90;              // 1-100, for encoding jpeg
  double calibration_period_s = 1.0;  // between calibration messages

  // The keys of the block, declared once (config/param_table.hpp).
  static const config::ParamTable<CameraStageParams>& table();
  // Reads the block; a relative video or folder path is taken from the
  // config file's directory. Throws config::ConfigError naming the key.
  static CameraStageParams load(const config::ConfigNode& node, const config::RobotConfig& robot);
};

class CameraStage final : public bus::Stage {
 public:
  // `source`: opened and checked against the camera (see registerCamera).
  CameraStage(CameraStageParams params, std::unique_ptr<capture::FrameSource> source);
  ~CameraStage() override;
  void start(bus::StageContext& ctx) override;
  void onTimer(Utime now) override;
  void collectHealth(bus::HealthReport& report) override;
  void stop() override;
  std::vector<std::string> outputChannels() const override;

 private:
  void captureLoop();

  CameraStageParams params_;
  std::vector<std::string> refused_settings_;
  std::unique_ptr<capture::Camera> camera_;
  bus::StageContext* ctx_ = nullptr;
  std::thread thread_;
  Utime next_calibration_ = 0;
  std::atomic<int64_t> wrong_size_{0};  // frames not at the camera's size, dropped
  capture::CameraCounters last_counters_;
};

// Role "camera". Opens the source while building the stage, so an unknown
// device, a size the device cannot give or an image size other than the
// robot file's is a configuration error (exit 2) naming the key.
void registerCamera(bus::StageRegistry& registry);

}  // namespace vslam::stages
