#pragma once
// The visual front-end of one camera (vSLAM paper section 4) without
// transport: the odometry it needs, recognition and measurement of known
// landmarks in a frame, and the window of three views that makes a new
// landmark where no known one covers the place. No LCM: the stage adapter
// (stages/frontend_stage) feeds it frames and odometry, publishes what a
// frame gives and keeps the recognition index in step with the landmark DB;
// tests drive it directly.
//
// Threads: odometry and landmarks may arrive on another thread than the
// frames; frames (extract(), track()) come from one thread.

#include <deque>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "config/robot_config.hpp"
#include "frontend/features.hpp"
#include "frontend/landmark_creation.hpp"
#include "frontend/landmark_index.hpp"
#include "frontend/pose_measurement.hpp"
#include "odometry/pose2.hpp"
#include "util/time.hpp"

namespace vslam::frontend {

// Index ids at or above this are landmarks awaiting their global id from the
// landmark DB: recognized (they cover their place, so it is not proposed
// twice) but never measured (a measurement names a global id).
inline constexpr int64_t kFirstPendingId = int64_t{1} << 62;

struct FrontendParams {
  config::CameraConfig camera;
  double creation_baseline_m = 0.20;   // odometry travel between the three views
  double max_view_span_s = 20.0;       // views older than this are dropped
  int max_measurements_per_frame = 4;  // recognized landmarks measured per frame, best first
  // A landmark covers the place (no new one is made) when a measurement of it
  // passes the pre-filter within this distance of its creation pose; 0: at
  // any distance. Measurement errors grow with that distance.
  double coverage_radius_m = 0.0;
  // A frame farther than this from any odometry reading has no pose: it is
  // tracked, but takes no part in landmark creation.
  Utime max_odometry_gap = 200000;
  SiftParams sift;
  CreationParams creation;
  RecognitionParams recognition;
  PoseMeasurementParams measurement;
  PrefilterParams prefilter;  // the stack's: whether a measurement covers the place
};

// One frame of the window: when, where by odometry, what it saw.
struct View {
  Utime utime = 0;
  Pose2 odometry;
  Features features;
};

struct LandmarkMeasurement {
  int64_t landmark_id = 0;  // a global id (never a pending one)
  PoseMeasurement measurement;
};

// A landmark made from the window: its first view is the landmark's frame.
struct NewLandmark {
  View first_view;
  CreatedLandmark landmark;
  // Its recognition model (points and the first view's descriptors) under `id`.
  LandmarkModel model(int64_t id) const;
};

struct FrameResult {
  std::vector<LandmarkMeasurement> measurements;  // most matches first
  int recognitions = 0;                           // landmarks recognized
  int measurement_failures = 0;                   // recognized, but no pose from them
  bool place_covered = false;  // a measurement the pre-filter accepts (near enough)
  bool have_odometry = false;  // false: the frame took no part in creation
  std::optional<NewLandmark> created;
  std::optional<std::string> creation_failure;  // why the window's three views made no landmark
  double recognition_ms = 0, measurement_ms = 0, creation_ms = 0;
};

class Frontend {
 public:
  explicit Frontend(FrontendParams params);
  const FrontendParams& params() const { return params_; }

  enum class OdometryVerdict { kAdded, kNotFinite, kNotNewer };
  // A cumulative odometry pose; readings not newer than the last are ignored.
  OdometryVerdict addOdometry(Utime t, const Pose2& pose);
  // The odometry pose at t, interpolated; false if no reading is near enough.
  bool odometryAt(Utime t, Pose2* pose) const;

  // SIFT features of a CV_8UC1 frame with this camera's extractor.
  void extract(const cv::Mat& gray, Features* out);
  // Recognizes and measures known landmarks in the frame's features, then
  // adds the frame to the creation window where no landmark covers the place.
  // A landmark made here is not in the index yet: the caller adds it under the
  // id it chooses (addLandmark(created->model(id))).
  FrameResult track(Utime t, Features features);

  // The recognition index (every camera's landmarks).
  void addLandmark(LandmarkModel model);
  void removeLandmark(int64_t id);
  size_t numLandmarks() const;

 private:
  void considerCreation(View view, FrameResult* result);

  FrontendParams params_;
  FeatureExtractor extractor_;
  LandmarkCreator creator_;
  MeasurementCamera measurement_camera_;
  mutable std::mutex index_mutex_;
  LandmarkIndex index_;
  mutable std::mutex odometry_mutex_;
  std::deque<std::pair<Utime, Pose2>> odometry_;  // recent cumulative poses
  std::deque<View> views_;                        // the creation window
};

}  // namespace vslam::frontend
