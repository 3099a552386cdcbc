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

#include <array>
#include <deque>
#include <limits>
#include <mutex>
#include <optional>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include "config/robot_config.hpp"
#include "frontend/features.hpp"
#include "frontend/landmark_creation.hpp"
#include "frontend/landmark_index.hpp"
#include "frontend/landmark_refinement.hpp"
#include "frontend/matching.hpp"
#include "frontend/pose_measurement.hpp"
#include "odometry/odometry_gate.hpp"
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
  // ...and, where this front-end's odometry saw the landmark made (and saw no
  // view jump since), when the measurement agrees with the odometry since
  // then (odometryAgrees): a repeated pattern recognized a period away from
  // where it was made is a look-alike, and its place still needs a landmark
  // of its own. 0: any measurement the pre-filter accepts covers.
  OdometryGate coverage_gate;
  // A frame farther than this from any odometry reading has no pose: it is
  // tracked, but takes no part in landmark creation.
  Utime max_odometry_gap = 200000;
  // A landmark made here is handed on at once and refined later: the frames
  // that see it until the robot has driven this far from its first view (or
  // twice as far along its path, or max_view_span_s has passed), at least
  // creation_baseline_m apart, refine its structure and scale
  // (landmark_refinement.hpp) and FrameResult::refined hands it on again.
  // 0: no refinement.
  double refine_distance_m = 0.0;
  // The view jumped (the robot was carried, or kidnapped): a frame finds
  // again fewer than this share of the previous frame's strongest features,
  // and fewer than this share of its largest-scale ones, although odometry
  // says the robot barely moved between them; tested only where the
  // thumbnails cannot tell or are unsure (below). 0: not tested.
  double view_jump_max_matched_share = 0.0;
  // The view jumped where the two frames' thumbnails are less alike than
  // this (thumbnailSimilarity), odometry as above. Where the thumbnails can
  // tell (contrast in both) and are sure (below), they decide, and the
  // features are not tested: they need no features (a dark room), a repeated
  // pattern's features found again across a carry do not hide it, nor does a
  // fast turn's blur make one. 0: not tested.
  double view_jump_min_thumbnail_similarity = 0.0;
  // Thumbnails alike at least view_jump_min_thumbnail_similarity but less
  // than this are not sure: the features are tested as well, and the view
  // jumped if they say so (a carry between two views of the same pattern,
  // whose thumbnails still correlate a little). 0: the thumbnails alone.
  double view_jump_features_below_similarity = 0.0;
  SiftParams sift;
  CreationParams creation;
  RefinementParams refinement;
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
  // Measurements the pre-filter accepts that disagree with the odometry since
  // their landmark was made (FrontendParams::coverage_gate): look-alikes,
  // which cover nothing.
  int odometry_disagreements = 0;
  bool have_odometry = false;  // false: the frame took no part in creation
  std::optional<NewLandmark> created;
  // A landmark made earlier (its first view names it) whose refinement was
  // due: its structure refined if report.refined, else as made.
  struct Refined {
    NewLandmark landmark;
    RefinementReport report;
  };
  std::optional<Refined> refined;
  std::optional<std::string> creation_failure;  // why the window's three views made no landmark
  // This frame against the previous one (view_jump_max_matched_share or
  // view_jump_min_thumbnail_similarity > 0): the share of the previous
  // frame's strongest features found again, or of its largest-scale ones if
  // more of those were, -1 if not tested (a gap, too few features, the robot
  // moved too far); the two frames' thumbnails' similarity
  // (thumbnailSimilarity), NaN if not tested (a gap, two plain views, the
  // robot moved too far); and whether the view jumped by either.
  double matched_share = -1;
  double thumbnail_similarity = std::numeric_limits<double>::quiet_NaN();
  bool view_jumped = false;
  Utime previous_utime = 0;
  // Wall time of the frame's parts (creation: refinement and the window of
  // views; continuity: the view-jump test).
  double recognition_ms = 0, measurement_ms = 0, creation_ms = 0, continuity_ms = 0;
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
  // A landmark made here is not in the index yet: the caller adds it under
  // the id it chooses (addLandmark(created->model(id))).
  FrameResult track(Utime t, Features features);

  // The recognition index (every camera's landmarks).
  void addLandmark(LandmarkModel model);
  void removeLandmark(int64_t id);
  size_t numLandmarks() const;
  size_t numRefiningLandmarks() const { return refining_.size(); }  // frames' thread only

 private:
  // A landmark made here whose refinement is not due yet.
  struct RefiningLandmark {
    NewLandmark made;
    LandmarkModel model;  // its points and descriptors, to find it in later frames
    std::array<Pose2, 3> creation_odometry;
    std::vector<LaterView> later;     // creation_baseline_m apart
    std::optional<LaterView> newest;  // the latest view, if nearer the last kept
    Pose2 last_view;                  // odometry of the last view kept for it
    double path_m = 0;                // odometry path length since view 3
    Pose2 path_end;                   // odometry at the last frame counted in path_m
  };

  // The odometry with its path totals, interpolated at t; nullopt if no
  // reading is near enough.
  std::optional<OdometryAt> odometryWithTotalsAt(Utime t) const;
  // Where a landmark was made in this front-end's odometry (anchorOf).
  struct Anchor {
    Utime created_utime = 0;
    OdometryAt odometry;
  };
  // `model`'s anchor, if this odometry agrees with its created_odometry.
  std::optional<Anchor> anchorOf(const LandmarkModel& model) const;

  void considerCreation(View view, FrameResult* result);
  // Compares the frame with the previous one (FrameResult::matched_share,
  // view_jumped) and keeps its strongest features for the next.
  void testContinuity(Utime t, const View& view, bool have_odometry, FrameResult* result);
  // Finds each refining landmark in the frame (ratio test against its
  // descriptors, then its pose measurement) and keeps the view: if far
  // enough from its last one, else aside as the newest (the refinement uses
  // the farthest view).
  void observeRefining(const Features& features, const Pose2& odometry);
  // Refines the first refining landmark that is due, into `result`.
  void refineDue(Utime t, const Pose2& odometry, FrameResult* result);

  FrontendParams params_;
  FeatureExtractor extractor_;
  LandmarkCreator creator_;
  MeasurementCamera measurement_camera_;
  mutable std::mutex index_mutex_;  // index_, anchors_, anchor_epoch_
  LandmarkIndex index_;
  // Where the landmarks this odometry saw made were made (anchorOf), by id.
  std::unordered_map<int64_t, Anchor> anchors_;
  Utime anchor_epoch_ = 0;  // the last view jump: landmarks made before it have no anchor
  mutable std::mutex odometry_mutex_;
  std::deque<std::pair<Utime, OdometryAt>> odometry_;  // recent cumulative poses
  std::deque<View> views_;                             // the creation window
  std::vector<RefiningLandmark> refining_;             // made, refinement not due yet
  RatioMatcher refining_matcher_;
  // The previous frame's strongest features, for testContinuity.
  struct PreviousFrame {
    Utime utime = 0;
    bool have_odometry = false;
    Pose2 odometry;
    cv::Mat strongest;  // descriptors of its kContinuityFeatures strongest features
    cv::Mat largest;    // and of its kContinuityFeatures largest-scale ones
    cv::Mat thumbnail;  // Features::thumbnail
  };
  std::optional<PreviousFrame> previous_;
  RatioMatcher continuity_matcher_;
};

}  // namespace vslam::frontend
