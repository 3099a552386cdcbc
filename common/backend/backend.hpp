#pragma once
// The back-end as the stage drives it, without LCM: cumulative odometry in,
// visual measurements in (pre-filter, alignment in time, particle filter
// update), estimates out, with counts of everything that was used or not.
//
//   Backend be(BackendParams{...});
//   be.addOdometry({utime, seq, odom_pose});         // every ODOMETRY message
//   MeasurementResult r = be.addMeasurement(m);      // every VISUAL_MEASUREMENT
//   r.status                                         // pre-filter verdict to republish
//   be.filter().estimate();                          // pose, covariance, ESS, kidnapped
//
// Time alignment. The particles are at the time of the newest odometry
// reading; a measurement is of the robot at its image's capture time, a
// little earlier (the front-end's latency) or, live, sometimes later. With
// the odometry of the last max_measurement_age_s kept, the measurement is
// moved to the particles' time by the odometry motion in between:
//   y_now = y (+) D,   D = odom(t_image)^-1 (+) odom(t_now)
// (interpolated at t_image), with covariance J_y R J_y^T + J_D Q(D) J_D^T.
// Older measurements, and ones more than max_measurement_lead_s newer than
// the newest odometry, are not used (counted).
//
// Map correction (optional, MapCorrectionParams): the measurements the
// filter found consistent, the odometry between them and the landmarks'
// creation times (addLandmarkCreation) also go into a pose graph; every
// solve_interval_s it is solved and its landmark poses replace the filter's
// (docs/backend.md, "Map correction").

#include <array>
#include <cstdint>
#include <deque>
#include <future>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <unordered_map>

#include "backend/odometry_calibration.hpp"
#include "backend/particle_filter.hpp"
#include "backend/pose_graph.hpp"
#include "backend/prefilter.hpp"
#include "odometry/motion_model.hpp"

namespace vslam::backend {

struct MapCorrectionParams {
  bool enabled = false;
  double solve_interval_s = 2.0;  // robot time between solves (each needs a new measurement)
  // A used measurement enters the graph when at most this fraction of the
  // particles found it an outlier (beyond the gate): the filter, localized,
  // tells aliased recognitions from loop closures better than the graph can.
  double max_outlier_fraction = 0.5;
  // At most one measurement per landmark per interval into the graph
  // (independently of the filter's landmark_min_interval_s). 0: all.
  double measurement_min_interval_s = 0.5;
  // After a kidnapping, a relocalized pose this far from where the odometry
  // carried the graph's newest node means the robot was moved (the graph's
  // odometry chain is broken there); nearer, it was a loop closure after a
  // long drift, which the filter cannot tell from a kidnapping, unless a
  // view jump came with it (ParticleFilter::robotWasMoved).
  double kidnap_jump_m = 1.5;
  double kidnap_jump_rad = 30 * M_PI / 180;
  // Nearer, it was still a move (a wheel slip: 0.6 m in a second or two)
  // when the jump is beyond what the odometry's noise allows over the path
  // since the map last pinned the robot (its drift span, below): squared
  // Mahalanobis distance of the jump under the motion model's covariance
  // over that path. A drift's loop closure comes after tens of metres of
  // path with nothing old in view. 0: no test.
  double kidnap_jump_mahalanobis_sq = 16.27;
  // Odometry kept to place a landmark's creation node: the front-end
  // announces a landmark after its third view, which may come many seconds
  // after the first (the creation pose) when the robot turns in place.
  double creation_max_age_s = 60.0;
  // The filter's landmarks take the graph's poses with this covariance.
  double landmark_sigma_xy_m = 0.02;
  double landmark_sigma_theta_rad = 0.5 * M_PI / 180;
  // Solve off the filter's path: a solve runs on a worker thread over a copy
  // of the graph, and the filter takes its result at the first measurement
  // `solve_result_after_s` of robot time after the solve began (waiting for
  // the worker if it is not done: the result is the same however fast the
  // machine, so a replay is repeatable). false: solved on the update that
  // triggers it, applied at once.
  bool solve_in_background = true;
  double solve_result_after_s = 0.2;
  PoseGraphParams graph;

  void validate() const;
};

struct BackendParams {
  FilterParams filter;
  MapCorrectionParams map_correction;
  OdometryCalibrationParams odometry_calibration;
  PrefilterParams prefilter;
  double max_step_m = 1.0;  // odometry jumps larger than this are faults, not motion
  double max_step_rad = M_PI / 2;
  double max_measurement_age_s = 5.0;   // odometry history kept to align measurements
  double max_measurement_lead_s = 0.5;  // newer than the newest odometry by more: not used
  // Measurements of one landmark closer in time than this to the last one
  // used are not used (kThinned): a landmark measured at camera rate gives
  // errors that are strongly correlated (they share the landmark's own 3-D
  // error), and treating them as independent makes the weights and the
  // landmark filters overconfident. 0: use every measurement.
  double landmark_min_interval_s = 0.0;
  // Sigma_vis growing with the distance d = |(y_x, y_y)| from the landmark's
  // creation pose: sigma_xy = sqrt(s0^2 + (k d)^2), likewise for theta. A
  // landmark's 3-D points carry depth errors (triangulated over a short
  // odometry baseline), so the measured pose errs roughly in proportion to
  // how far the robot is from where the landmark was built. 0: the paper's
  // constant Sigma_vis.
  double measurement_sigma_xy_per_m = 0.0;
  double measurement_sigma_theta_rad_per_m = 0.0;

  void validate() const;
};

struct MeasurementInput {
  int64_t utime = 0;  // capture time of the image, microseconds
  int64_t landmark_id = 0;
  Pose2 relative;  // y: robot now in the landmark's creation frame
  double proj_err_rms_px = 0;
  int num_points = 0;
  double slope = 0;
  std::string camera;  // that took the image ("": unknown; Backend::noteViewJump)
};

// What happened to a measurement after the pre-filter.
enum class MeasurementUse {
  kUsed,             // updated the filter (or initialised its landmark)
  kRejected,         // pre-filter rejected it (MeasurementResult::status says why)
  kInvalidLandmark,  // landmark id < 0
  kNoOdometry,       // no odometry yet to place it in time
  kTooOld,           // older than the odometry history
  kTooNew,           // newer than the newest odometry by more than max_measurement_lead_s
  kThinned,          // within landmark_min_interval_s of the landmark's last used measurement
  kRetired,          // its landmark disagrees with the odometry (map correction's odometry gate)
};
constexpr int kNumMeasurementUse = 8;
const char* toString(MeasurementUse u);

// What map correction made of a relocalization (Backend::joinOrBreakAfterKidnap).
struct RelocalizationJoin {
  bool broken = false;  // the graph's odometry chain was broken there (the robot was moved)
  double jump_m = 0;    // the relocalized pose against the odometry's from the graph's newest node
  double jump_rad = 0;
  double span_m = 0;  // the robot's drift span then
  double span_rad = 0;
  double jump_mahalanobis_sq = 0;  // the jump under the odometry's covariance over that span
};

struct MeasurementResult {
  MeasurementStatus status = MeasurementStatus::kUnfiltered;  // pre-filter verdict
  MeasurementUse use = MeasurementUse::kRejected;
  UpdateReport update;  // valid when use == kUsed
  // At a relocalization with map correction on (and a graph node to join to).
  std::optional<RelocalizationJoin> join;
};

struct BackendCounters {
  std::array<int64_t, kNumMeasurementStatus> status{};  // by MeasurementStatus
  std::array<int64_t, kNumMeasurementUse> use{};        // by MeasurementUse
  int64_t landmarks_initialized = 0;
  int64_t kidnaps_detected = 0;
  int64_t recoveries = 0;
  int64_t kidnaps_cancelled = 0;  // recoveries that went back to the pose before (look-alikes)
  int64_t drift_corrections = 0;  // evidence within the drift gate (KidnapParams)
  // Known look-alikes' measurements that were not consistent: weighed
  // nothing (UpdateKind::kIgnored).
  int64_t look_alike_measurements_ignored = 0;
  // Landmarks first seen while kidnapped, mapped at the relocalization from
  // their newest measurement carried by the odometry (UpdateReport::deferred).
  int64_t landmarks_mapped_after_relocalization = 0;
  // Landmarks placed before a kidnapping was detected that a measurement
  // after the relocalization put where it moved them (UpdateReport::moved);
  // the filter keeps them, the pose graph drops them.
  int64_t landmarks_moved_after_relocalization = 0;
  int64_t resamplings = 0;
  int64_t odometry_steps = 0;
  int64_t odometry_ignored = 0;  // stale, invalid, reset, implausible
  // Map correction.
  int64_t landmarks_in_graph = 0;         // creation times placed in the pose graph
  int64_t landmark_creations_unused = 0;  // creation time outside the odometry history
  int64_t graph_measurements = 0;         // measurements added to the pose graph
  int64_t graph_solves = 0;
  int64_t graph_solve_failures = 0;
  int64_t graph_odometry_breaks = 0;  // kidnappings (and odometry resets) that split the graph
  // Segments begun at a moved robot's relocalization, moved with the drift
  // correction that showed the relocalization off (Backend::moveRelocalizedSegment).
  int64_t graph_segments_moved = 0;
  double graph_last_solve_ms = 0;
  // Updates that waited for the background solve (it took longer than the
  // solve interval of robot time: a replay faster than real time, or a graph
  // too big for the machine), and the wall time they waited.
  int64_t graph_solve_waits = 0;
  double graph_solve_wait_ms = 0;
};

class Backend {
 public:
  explicit Backend(BackendParams params);
  ~Backend();  // waits for a solve in the background
  Backend(const Backend&) = delete;
  Backend& operator=(const Backend&) = delete;

  OdometryIncrements::Outcome addOdometry(const OdometryReading& reading);
  MeasurementResult addMeasurement(const MeasurementInput& m);
  // A landmark's creation time (the reference view's capture time: its pose
  // is the robot pose then). Only map correction uses it; a landmark whose
  // creation time is unknown or outside the odometry history stays out of
  // the pose graph (the filter still uses it). Returns whether it went in.
  bool addLandmarkCreation(int64_t landmark_id, int64_t created_utime);
  // A saved map to continue in (ParticleFilter::loadMap); map correction
  // keeps its landmarks where they are and ties the new path to them
  // (PoseGraph::addMapLandmark). Before the first odometry.
  void loadMap(const std::vector<ParticleFilter::KnownLandmark>& landmarks);
  // A camera's view jumped at `utime` (ParticleFilter::noteViewJump). When
  // every camera heard from (by a measurement or a jump) in the last
  // kActiveCameraS has jumped within kSimultaneousJumpS of it, two cameras
  // at least, none of them after another jump less than
  // KidnapParams::view_jump_window_s before, and
  // KidnapParams::declare_on_every_view_jump, the robot was moved: the
  // kidnapping is declared (ParticleFilter::declareMoved) and this returns
  // true.
  bool noteViewJump(const std::string& camera, int64_t utime);

  const ParticleFilter& filter() const { return filter_; }
  ParticleFilter& filter() { return filter_; }
  const BackendCounters& counters() const { return counters_; }
  // The newest odometry reading the particles are at (none before the first).
  const std::optional<OdometryReading>& lastOdometry() const { return increments_.last(); }
  // The pose graph of map correction (nullptr when disabled).
  const PoseGraph* poseGraph() const { return graph_ ? &*graph_ : nullptr; }
  // The odometry's noise and biases estimated from the measurements
  // (invalid when odometry_calibration is disabled or has too few pairs).
  OdometryNoiseEstimate odometryNoise() const {
    return calibration_ ? calibration_->estimate() : OdometryNoiseEstimate{};
  }

 private:
  // Seconds of odometry kept behind the newest reading.
  double historySpanS() const;
  // The odometry at `utime`, interpolated in the history; none (and *why)
  // if `utime` is more than max_age_s before the newest reading or after it
  // by more than max_measurement_lead_s.
  std::optional<OdometryAt> odometryAt(int64_t utime, double max_age_s, MeasurementUse* why) const;
  // The filter's estimate moved back by the odometry to a time whose
  // odometry is `then`.
  Pose2 estimateAt(const Pose2& then) const;
  Observation alignedObservation(const MeasurementInput& m, const Pose2& then) const;
  // A measurement the filter found consistent (or not: then it is dropped).
  void addToGraph(const MeasurementInput& m, const OdometryAt& then, bool consistent);
  void correctMap(int64_t utime);  // at the measurement time `utime`
  // The background solve's result, into the graph and the filter.
  void takeSolution();
  // The filter takes a solved graph's landmarks, and the correction at the
  // newest node it had: `solved_at` (that node's pose in the solution, or
  // the graph's) against the filter's estimate there when the solve began.
  void applyCorrection(const Pose2& solved_at, const Pose2& filter_at);
  std::optional<RelocalizationJoin> joinOrBreakAfterKidnap();
  // At a relocalization: the landmarks first seen while kidnapped, from
  // their newest measurement moved to now by the odometry since.
  void mapDeferredLandmarks();

  struct HistoryEntry {
    OdometryReading reading;
    double distance_m;    // path driven since the start
    double rotation_rad;  // and turned
  };

  BackendParams params_;
  ParticleFilter filter_;
  OdometryIncrements increments_;
  std::deque<HistoryEntry> history_;  // accepted readings, oldest first
  double distance_m_ = 0, rotation_rad_ = 0;
  std::optional<PoseGraph> graph_;
  std::optional<OdometryNoiseEstimator> calibration_;
  // A measurement the filter found consistent also calibrates the odometry.
  void calibrate(const MeasurementInput& m, const OdometryAt& then);
  int64_t next_solve_utime_ = 0;
  // Newest measurement of each landmark first seen in this kidnapped period.
  std::map<int64_t, MeasurementInput> deferred_;
  int64_t graph_measurements_since_solve_ = 0;
  std::unordered_map<int64_t, int64_t> graph_last_used_;  // landmark id -> utime in the graph
  int newest_graph_node_ = -1;      // the newest measurement's node in the graph...
  Pose2 newest_graph_node_filter_;  // ...and the filter's estimate there
  // Drift span: the odometry (path driven, turned) since the map last
  // pinned a pose, an upper bound standing in for its uncertainty against
  // the map. The robot's grows as it drives and is zero after a
  // relocalization; a landmark takes the robot's at its creation; a
  // consistent measurement passes the smaller on (noteConsistent); a saved
  // map's landmarks have none. Tells a slip from a drift's loop closure
  // (kidnap_jump_mahalanobis_sq).
  struct DriftSpan {
    double distance_m = 0, rotation_rad = 0;
    double size() const { return distance_m + rotation_rad; }  // to order two spans
  };
  DriftSpan robotDriftSpan(const OdometryAt& at) const {
    return {at.distance_m - drift_origin_.distance_m, at.rotation_rad - drift_origin_.rotation_rad};
  }
  void noteConsistent(int64_t landmark_id, const OdometryAt& then, const Pose2& relative);
  // The filter corrected a moved robot's recent relocalization by `shift`
  // (a drift correction): the graph's segment since follows.
  void moveRelocalizedSegment(int64_t utime, const Pose2& shift);
  DriftSpan drift_origin_;  // the odometry totals at which the robot's span was zero
  std::unordered_map<int64_t, DriftSpan> landmark_drift_;
  // The solve in the background (solve_in_background): the copy it works on
  // and the newest node with the filter's estimate when it began.
  std::unique_ptr<PoseGraph> solving_graph_;
  std::future<PoseGraphSolveSummary> solving_;
  int solving_newest_node_ = -1;
  Pose2 solving_newest_filter_;
  int64_t solving_result_utime_ = 0;  // its result is taken at this measurement time
  std::unordered_map<int64_t, int64_t>
      last_used_;  // landmark id -> utime of its last used measurement
  BackendCounters counters_;
  // Each camera's newest measurement or view jump, and its newest jump
  // (noteViewJump); at most kMaxCameras (names come from the network).
  struct CameraActivity {
    int64_t heard_utime = 0;
    int64_t jump_utime = std::numeric_limits<int64_t>::min();
    int64_t previous_jump_utime = std::numeric_limits<int64_t>::min();  // the jump before
  };
  std::map<std::string, CameraActivity> cameras_;
  void noteCamera(const std::string& camera, int64_t utime);
};

}  // namespace vslam::backend
