#pragma once
// vslam-frontend: the vSLAM visual front-end (paper section 4) for one
// camera, over the algorithms of common/frontend.
//
// Every frame (newest wins; stale frames are dropped, counted in health):
// SIFT features -> recognition of known landmarks (of every camera) -> a
// visual measurement per recognized landmark, published unfiltered on
// VISUAL_MEASUREMENT (the back-end's pre-filter judges it). Where no landmark
// gives a measurement the pre-filter would accept, the front-end collects
// three views ~creation_baseline_m apart by odometry and creates a new
// landmark from them, published on LANDMARK_PROPOSAL.
//
// Landmark ids: until the landmark DB manager assigns global ids, each
// front-end numbers its landmarks camera_number * 1e9 + n (camera_number =
// 1-based position in the robot file), uses that id in its measurements and
// publishes it in the proposal; front-ends add each other's proposals to
// their index, so every camera recognizes every landmark.

#include <deque>
#include <memory>
#include <mutex>
#include <vslam/image_t.hpp>
#include <vslam/landmark_update_t.hpp>
#include <vslam/odometry_t.hpp>

#include "bus/latest_worker.hpp"
#include "bus/stage.hpp"
#include "bus/stage_registry.hpp"
#include "frontend/landmark_creation.hpp"
#include "frontend/landmark_index.hpp"
#include "frontend/pose_measurement.hpp"

namespace vslam::stages {

struct FrontendParams {
  config::CameraConfig camera;
  int camera_number = 1;  // 1-based index of the camera in the robot file
  std::string odometry_channel;
  std::string measurement_channel;
  std::string proposal_channel;
  double creation_baseline_m = 0.20;   // odometry travel between the three views
  double max_view_span_s = 20.0;       // views older than this are dropped
  int max_measurements_per_frame = 4;  // recognized landmarks measured per frame, best first
  frontend::SiftParams sift;
  frontend::CreationParams creation;
  frontend::RecognitionParams recognition;
  frontend::PoseMeasurementParams measurement;
  frontend::PrefilterParams prefilter;  // only to decide whether this place needs a landmark

  static FrontendParams load(const config::ConfigNode& node, const config::RobotConfig& robot);
};

class FrontendStage final : public bus::Stage {
 public:
  explicit FrontendStage(FrontendParams params);
  ~FrontendStage() override;
  void start(bus::StageContext& ctx) override;
  void drain() override;
  void stop() override;
  void collectHealth(bus::HealthReport& report) override;
  std::vector<std::string> outputChannels() const override {
    return {params_.measurement_channel, params_.proposal_channel};
  }

 private:
  struct View {
    Utime utime = 0;
    Pose2 odometry;
    frontend::Features features;
  };
  struct Stats {
    int64_t frames = 0, features = 0, recognitions = 0, measurements = 0, measurement_failures = 0;
    int64_t created = 0, creation_failures = 0, foreign_landmarks = 0, no_odometry = 0;
    double sift_ms = 0, recognition_ms = 0, measurement_ms = 0, creation_ms = 0;
  };

  void onImage(const vslam::image_t& msg);
  void onOdometry(const vslam::odometry_t& msg);
  void onProposal(const vslam::landmark_update_t& msg);
  void process(vslam::image_t& msg);
  bool toGray(const vslam::image_t& msg, cv::Mat* gray);
  bool odometryAt(Utime t, Pose2* pose);
  void considerCreation(View view, bool place_covered);
  void publishProposal(const View& view1, const frontend::CreatedLandmark& lm, int64_t id);

  FrontendParams params_;
  bus::StageContext* ctx_ = nullptr;
  std::unique_ptr<bus::LatestWinsWorker<vslam::image_t>> worker_;
  frontend::FeatureExtractor extractor_;
  frontend::LandmarkCreator creator_;
  frontend::MeasurementCamera measurement_camera_;
  std::mutex index_mutex_;  // proposals of other front-ends arrive on the LCM thread
  frontend::LandmarkIndex index_;
  std::mutex odometry_mutex_;
  std::deque<std::pair<Utime, Pose2>> odometry_;  // recent cumulative poses
  std::deque<View> views_;
  cv::Mat gray_;
  int64_t next_landmark_ = 1;
  int64_t measurement_seq_ = 0;
  std::mutex stats_mutex_;
  Stats stats_, last_;
};

void registerFrontend(bus::StageRegistry& registry);

}  // namespace vslam::stages
