#include "backend/backend.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>

namespace vslam::backend {

namespace {
// A measurement at most this fraction of the particles gates out counts as
// consistent for the odometry calibration.
constexpr double kConsistentOutlierFraction = 0.5;
// noteViewJump: a camera heard from this recently is one of the robot's
// (a camera that has stopped is not waited for)...
constexpr double kActiveCameraS = 10.0;
// ...and jumps of every camera this close in time are one move: the same
// instant, give or take a frame of cameras not triggered together (at 10
// Hz). Not more: false jumps of two cameras half a second apart are not
// rare (the built-in kidnap scenario, 8 s after its carry).
constexpr double kSimultaneousJumpS = 0.15;
constexpr size_t kMaxCameras = 16;
}  // namespace

const char* toString(MeasurementUse u) {
  switch (u) {
    case MeasurementUse::kUsed:
      return "used";
    case MeasurementUse::kRejected:
      return "rejected by the pre-filter";
    case MeasurementUse::kInvalidLandmark:
      return "invalid landmark id";
    case MeasurementUse::kNoOdometry:
      return "no odometry yet";
    case MeasurementUse::kTooOld:
      return "older than the odometry history";
    case MeasurementUse::kTooNew:
      return "newer than the newest odometry";
    case MeasurementUse::kThinned:
      return "too soon after the landmark's last used measurement";
    case MeasurementUse::kRetired:
      return "its landmark disagrees with the odometry";
  }
  return "?";
}

void MapCorrectionParams::validate() const {
  graph.validate();
  if (!(solve_interval_s >= 0))
    throw std::invalid_argument("backend: map_correction.solve_interval_s must be >= 0");
  if (!(max_outlier_fraction >= 0 && max_outlier_fraction <= 1))
    throw std::invalid_argument("backend: map_correction.max_outlier_fraction must be in [0, 1]");
  if (!(landmark_sigma_xy_m > 0) || !(landmark_sigma_theta_rad > 0))
    throw std::invalid_argument("backend: map_correction landmark sigmas must be > 0");
  if (!(kidnap_jump_m > 0) || !(kidnap_jump_rad > 0))
    throw std::invalid_argument("backend: map_correction kidnap jump thresholds must be > 0");
  if (!(kidnap_jump_mahalanobis_sq >= 0))
    throw std::invalid_argument("backend: map_correction.kidnap_jump_mahalanobis_sq must be >= 0");
  if (!(creation_max_age_s > 0))
    throw std::invalid_argument("backend: map_correction.creation_max_age_s must be > 0");
  if (!(solve_result_after_s >= 0))
    throw std::invalid_argument("backend: map_correction.solve_result_after_s must be >= 0");
  if (!(measurement_min_interval_s >= 0))
    throw std::invalid_argument("backend: map_correction.measurement_min_interval_s must be >= 0");
}

void BackendParams::validate() const {
  filter.validate();
  if (map_correction.enabled) map_correction.validate();
  if (odometry_calibration.enabled) odometry_calibration.validate();
  prefilter.validate();
  if (!(max_step_m > 0) || !(max_step_rad > 0))
    throw std::invalid_argument("backend: max_step_m and max_step_rad must be > 0");
  if (!(measurement_sigma_xy_per_m >= 0) || !(measurement_sigma_theta_rad_per_m >= 0))
    throw std::invalid_argument("backend: measurement sigma growth rates must be >= 0");
  if (!(landmark_min_interval_s >= 0))
    throw std::invalid_argument("backend: landmark_min_interval_s must be >= 0");
  if (!(max_measurement_age_s > 0) || !(max_measurement_lead_s >= 0))
    throw std::invalid_argument(
        "backend: max_measurement_age_s must be > 0 and max_measurement_lead_s >= 0");
}

Backend::Backend(BackendParams params)
    : params_((params.validate(), std::move(params))),
      filter_(params_.filter),
      increments_(params_.max_step_m, params_.max_step_rad) {
  if (params_.map_correction.enabled) graph_.emplace(params_.map_correction.graph);
  if (params_.odometry_calibration.enabled) calibration_.emplace(params_.odometry_calibration);
}

OdometryIncrements::Outcome Backend::addOdometry(const OdometryReading& reading) {
  Pose2 step;
  const auto outcome = increments_.add(reading, &step);
  switch (outcome) {
    case OdometryIncrements::Outcome::kStep:
      filter_.predict(step);
      distance_m_ += std::hypot(step.x, step.y);
      rotation_rad_ += std::abs(step.theta);
      ++counters_.odometry_steps;
      break;
    case OdometryIncrements::Outcome::kFirst:
      break;
    case OdometryIncrements::Outcome::kReset:
    case OdometryIncrements::Outcome::kImplausible:
      // A new odometry frame: the history no longer relates to it, nor do
      // the pose graph's odometry edges.
      history_.clear();
      if (calibration_) calibration_->breakOdometry();
      if (graph_ && graph_->numNodes() > 0) {
        graph_->breakOdometry(reading.utime);
        ++counters_.graph_odometry_breaks;
      }
      ++counters_.odometry_ignored;
      break;
    case OdometryIncrements::Outcome::kStale:
    case OdometryIncrements::Outcome::kInvalid:
      ++counters_.odometry_ignored;
      return outcome;
  }
  history_.push_back({reading, distance_m_, rotation_rad_});
  if (graph_ && graph_->numNodes() == 0 && !filter_.kidnapped()) {
    // The graph's fixed first node: the filter's frame is the robot pose at
    // start-up, or, starting in a saved map at an unknown pose, the map's
    // frame once the filter has relocalized in it (until then its estimate
    // is in no frame, and a node fixed there would drag the filter into one
    // at the first correction).
    graph_->addNode(reading.utime, {reading.pose, distance_m_, rotation_rad_},
                    filter_.estimate().mean);
  }
  const double keep_s = historySpanS();
  const auto keep_us = static_cast<int64_t>(keep_s * 1e6);
  // Keep one reading older than the window: times inside it interpolate.
  while (history_.size() > 2 && history_[1].reading.utime < reading.utime - keep_us) {
    history_.pop_front();
  }
  return outcome;
}

std::optional<OdometryAt> Backend::odometryAt(int64_t utime, double max_age_s,
                                              MeasurementUse* why) const {
  if (history_.empty()) {
    *why = MeasurementUse::kNoOdometry;
    return std::nullopt;
  }
  const HistoryEntry& newest = history_.back();
  if (utime >= newest.reading.utime) {
    if (static_cast<double>(utime - newest.reading.utime) > params_.max_measurement_lead_s * 1e6) {
      *why = MeasurementUse::kTooNew;
      return std::nullopt;
    }
    // At most a little ahead: the robot's newest known pose.
    return OdometryAt{newest.reading.pose, newest.distance_m, newest.rotation_rad};
  }
  if (utime < history_.front().reading.utime ||
      static_cast<double>(newest.reading.utime - utime) > max_age_s * 1e6) {
    *why = MeasurementUse::kTooOld;
    return std::nullopt;
  }
  // history_ is in increasing utime (readings with non-increasing seq are dropped,
  // and seq increases with time); find the bracketing pair.
  size_t hi = history_.size() - 1;
  while (hi > 0 && history_[hi - 1].reading.utime > utime) --hi;
  const HistoryEntry& a = history_[hi - 1];
  const HistoryEntry& b = history_[hi];
  const double span = static_cast<double>(b.reading.utime - a.reading.utime);
  const double f = span > 0 ? static_cast<double>(utime - a.reading.utime) / span : 1.0;
  return interpolateOdometry({a.reading.pose, a.distance_m, a.rotation_rad},
                             {b.reading.pose, b.distance_m, b.rotation_rad}, f);
}

Pose2 Backend::estimateAt(const Pose2& then) const {
  const Pose2 d = then.between(history_.back().reading.pose);
  return filter_.estimate().mean.compose(d.inverse());
}

std::optional<RelocalizationJoin> Backend::joinOrBreakAfterKidnap() {
  // Was it a kidnapping? The filter cannot tell one from a loop closure
  // after a long drift (paper 6.2); a view jump can (robotWasMoved), and so
  // can the size of the jump. If the robot was moved, or the pose it
  // relocalized to is far from where the odometry carried the graph's
  // newest node, no odometry edge may join the nodes before and after.
  // So can a jump nearer than that but beyond the odometry's noise over
  // the robot's drift span: the odometry went wrong (a wheel slip).
  // Otherwise it was a loop closure, the most valuable constraint the graph
  // gets. (Tuning home 30: a carry of 1.5 m, relocalized 1.44 m from the
  // odometry's pose, was joined, and the graph pulled the estimate back.)
  const HistoryEntry& now = history_.back();
  const DriftSpan span = robotDriftSpan({now.reading.pose, now.distance_m, now.rotation_rad});
  drift_origin_ = {now.distance_m, now.rotation_rad};  // relocalized: pinned to the map again
  if (newest_graph_node_ < 0) return std::nullopt;
  const Pose2 predicted =
      graph_->nodePose(newest_graph_node_)
          .compose(graph_->nodeOdometry(newest_graph_node_).pose.between(now.reading.pose));
  const Pose2 relocalized = filter_.estimate().mean;
  RelocalizationJoin join;
  join.jump_m = std::hypot(relocalized.x - predicted.x, relocalized.y - predicted.y);
  join.jump_rad = std::abs(wrapAngle(relocalized.theta - predicted.theta));
  join.span_m = span.distance_m;
  join.span_rad = span.rotation_rad;
  const PoseGraph::OdometrySigmas o = graph_->odometrySigmas(span.distance_m, span.rotation_rad);
  join.jump_mahalanobis_sq = join.jump_m * join.jump_m / (o.xy * o.xy) +
                             join.jump_rad * join.jump_rad / (o.theta * o.theta);
  const double gate_d2 = params_.map_correction.kidnap_jump_mahalanobis_sq;
  join.broken = filter_.robotWasMoved() || join.jump_m > params_.map_correction.kidnap_jump_m ||
                join.jump_rad > params_.map_correction.kidnap_jump_rad ||
                (gate_d2 > 0 && join.jump_mahalanobis_sq > gate_d2);
  if (join.broken) {
    graph_->breakOdometry(now.reading.utime);
    ++counters_.graph_odometry_breaks;
  }
  return join;
}

void Backend::noteConsistent(int64_t landmark_id, const OdometryAt& then, const Pose2& relative) {
  // A measurement ties the robot to the landmark's creation pose about as
  // well as odometry over the distance between them would (the graph's
  // measurement sigma grows with that distance too); the robot and the
  // landmark each take the smaller span of the two ways. So a landmark made
  // a moment ago and tracked since pins nothing new, and one made when the
  // robot was pinned, measured near its creation pose, closes a loop.
  const double away_m = std::hypot(relative.x, relative.y);
  const double away_rad = std::abs(relative.theta);
  const auto it = landmark_drift_.find(landmark_id);
  DriftSpan via_landmark = it != landmark_drift_.end() ? it->second : DriftSpan{};
  via_landmark.distance_m += away_m;
  via_landmark.rotation_rad += away_rad;
  const DriftSpan robot = robotDriftSpan(then);
  if (via_landmark.size() < robot.size()) {
    drift_origin_ = {then.distance_m - via_landmark.distance_m,
                     then.rotation_rad - via_landmark.rotation_rad};
  } else if (it != landmark_drift_.end()) {
    const DriftSpan via_robot{robot.distance_m + away_m, robot.rotation_rad + away_rad};
    if (via_robot.size() < it->second.size()) it->second = via_robot;
  }
}

void Backend::moveRelocalizedSegment(int64_t utime, const Pose2& shift) {
  // A drift correction this soon after a moved robot's relocalization says
  // the relocalization was off (generated home 1239: 0.45 m, two
  // corrections towards the truth). The graph's segment begun there is tied
  // to the map by the measurements that agreed with the wrong pose, and the
  // filter's newer measurements cannot outweigh them at once: the next
  // solve would put the particles back where the correction took them from
  // (applyCorrection), twice in 1239, until a false kidnapping 21 s later.
  // So the segment moves with the particles and drops those measurements;
  // a solve begun before is stale.
  if (!graph_->moveSegment(utime, shift).has_value()) return;  // the fixed origin's segment
  if (solving_.valid()) {
    solving_.wait();
    solving_ = {};
    solving_graph_.reset();
  }
  if (newest_graph_node_ >= 0 &&
      graph_->nodeSegment(newest_graph_node_) == graph_->segmentAt(utime))
    newest_graph_node_filter_ = shift.compose(newest_graph_node_filter_);
  ++counters_.graph_segments_moved;
}

void Backend::loadMap(const std::vector<ParticleFilter::KnownLandmark>& landmarks) {
  if (graph_ && (graph_->numNodes() > 0 || graph_->numLandmarks() > 0))
    throw std::logic_error("backend: a saved map is loaded before the run begins");
  filter_.loadMap(landmarks);
  if (!graph_) return;
  for (const ParticleFilter::KnownLandmark& l : landmarks)
    if (filter_.slotOf(l.id) >= 0) graph_->addMapLandmark(l.id, toPose(l.estimate.mean));
}

void Backend::noteCamera(const std::string& camera, int64_t utime) {
  if (camera.empty()) return;
  auto it = cameras_.find(camera);
  if (it == cameras_.end()) {
    if (cameras_.size() >= kMaxCameras) {
      // Make room by the camera heard from longest ago (a stray name).
      auto oldest = std::min_element(cameras_.begin(), cameras_.end(), [](auto& a, auto& b) {
        return a.second.heard_utime < b.second.heard_utime;
      });
      cameras_.erase(oldest);
    }
    it = cameras_.emplace(camera, CameraActivity{}).first;
  }
  it->second.heard_utime = std::max(it->second.heard_utime, utime);
}

bool Backend::noteViewJump(const std::string& camera, int64_t utime) {
  filter_.noteViewJump(utime);
  noteCamera(camera, utime);
  if (camera.empty()) return false;
  CameraActivity& jumped = cameras_.at(camera);
  if (utime > jumped.jump_utime) {
    jumped.previous_jump_utime = jumped.jump_utime;
    jumped.jump_utime = utime;
  }
  const KidnapParams& kp = params_.filter.kidnap;
  if (!kp.declare_on_every_view_jump || filter_.kidnapped()) return false;
  constexpr int64_t kNever = std::numeric_limits<int64_t>::min();
  const auto active_us = static_cast<int64_t>(kActiveCameraS * 1e6);
  const auto together_us = static_cast<int64_t>(kSimultaneousJumpS * 1e6);
  const auto steady_us = static_cast<int64_t>(kp.view_jump_window_s * 1e6);
  int active = 0;
  for (const auto& [name, c] : cameras_) {
    if (utime - c.heard_utime > active_us) continue;  // stopped, or not one of this robot's
    ++active;
    if (c.jump_utime == kNever || std::abs(utime - c.jump_utime) > together_us) return false;
    // A camera whose view keeps jumping while the robot stays put (people
    // walking past it, motion blur) cannot tell a move: in the built-in
    // people scenario both cameras jump every few seconds, and two such
    // jumps a frame apart declared a kidnapping, cancelled 1.4 s later.
    if (c.previous_jump_utime != kNever && c.jump_utime - c.previous_jump_utime < steady_us)
      return false;
  }
  if (active < 2 || !filter_.declareMoved(utime)) return false;
  // As a kidnapping the measurements declare (addMeasurement).
  ++counters_.kidnaps_detected;
  deferred_.clear();
  if (calibration_) calibration_->breakOdometry();
  return true;
}

bool Backend::addLandmarkCreation(int64_t landmark_id, int64_t created_utime) {
  if (!graph_ || graph_->hasLandmark(landmark_id) || landmark_id < 0) return false;
  if (filter_.kidnapped()) {
    // Where the robot is is unknown, and whether the odometry since the
    // last node holds (a kidnapping or not) is decided at the recovery.
    ++counters_.landmark_creations_unused;
    return false;
  }
  MeasurementUse why = MeasurementUse::kUsed;
  const std::optional<OdometryAt> then =
      odometryAt(created_utime, params_.map_correction.creation_max_age_s, &why);
  if (!then || graph_->numNodes() == 0) {
    ++counters_.landmark_creations_unused;
    return false;
  }
  const int node = graph_->addNode(created_utime, *then, estimateAt(then->pose));
  graph_->addLandmark(landmark_id, node);
  // A landmark's creation pose is as far from the map as the robot was.
  const DriftSpan span = robotDriftSpan(*then);
  landmark_drift_[landmark_id] = {std::max(0.0, span.distance_m), std::max(0.0, span.rotation_rad)};
  ++counters_.landmarks_in_graph;
  return true;
}

void Backend::addToGraph(const MeasurementInput& m, const OdometryAt& then, bool consistent) {
  if (!consistent || !graph_->hasLandmark(m.landmark_id)) return;
  noteConsistent(m.landmark_id, then, m.relative);
  if (params_.map_correction.measurement_min_interval_s > 0) {
    const auto last = graph_last_used_.find(m.landmark_id);
    const auto min_us =
        static_cast<int64_t>(params_.map_correction.measurement_min_interval_s * 1e6);
    if (last != graph_last_used_.end() && m.utime >= last->second &&
        m.utime - last->second < min_us)
      return;
  }
  if (std::hypot(m.relative.x, m.relative.y) > graph_->params().max_measurement_distance_m) return;
  const Pose2 filter_then = estimateAt(then.pose);
  const int node = graph_->addNode(m.utime, then, filter_then);
  if (!graph_->addMeasurement(m.landmark_id, node, m.relative)) return;
  graph_last_used_[m.landmark_id] = m.utime;
  ++counters_.graph_measurements;
  ++graph_measurements_since_solve_;
  if (newest_graph_node_ < 0 || m.utime >= graph_->nodeTime(newest_graph_node_)) {
    newest_graph_node_ = node;
    newest_graph_node_filter_ = filter_then;
  }
  if (m.utime >= next_solve_utime_) {
    correctMap(m.utime);
    next_solve_utime_ =
        m.utime + static_cast<int64_t>(params_.map_correction.solve_interval_s * 1e6);
  }
}

Backend::~Backend() {
  if (solving_.valid()) solving_.wait();
}

void Backend::takeSolution() {
  if (solving_.wait_for(std::chrono::seconds(0)) != std::future_status::ready) {
    const auto t0 = std::chrono::steady_clock::now();
    solving_.wait();
    ++counters_.graph_solve_waits;
    counters_.graph_solve_wait_ms +=
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  }
  const PoseGraphSolveSummary s = solving_.get();
  counters_.graph_last_solve_ms = s.ms;
  if (s.solved) {
    ++counters_.graph_solves;
    graph_->adoptSolution(*solving_graph_);
    applyCorrection(graph_->nodePose(solving_newest_node_), solving_newest_filter_);
  } else {
    ++counters_.graph_solve_failures;
  }
  solving_graph_.reset();
}

void Backend::correctMap(int64_t utime) {
  const bool background = params_.map_correction.solve_in_background;
  if (solving_.valid()) takeSolution();  // begun at the previous solve time
  if (graph_measurements_since_solve_ == 0) return;
  graph_measurements_since_solve_ = 0;
  if (background) {
    graph_->prune();
    solving_graph_ = std::make_unique<PoseGraph>(*graph_);
    solving_newest_node_ = newest_graph_node_;
    solving_newest_filter_ = newest_graph_node_filter_;
    solving_result_utime_ =
        utime + static_cast<int64_t>(params_.map_correction.solve_result_after_s * 1e6);
    solving_ = std::async(std::launch::async, [g = solving_graph_.get()] { return g->solve(); });
    return;
  }
  const PoseGraphSolveSummary s = graph_->solve();
  counters_.graph_last_solve_ms = s.ms;
  if (!s.solved) {
    ++counters_.graph_solve_failures;
    return;
  }
  ++counters_.graph_solves;
  applyCorrection(graph_->nodePose(newest_graph_node_), newest_graph_node_filter_);
}

void Backend::applyCorrection(const Pose2& solved_at, const Pose2& filter_at) {
  std::vector<ParticleFilter::CorrectedLandmark> landmarks;
  for (const auto& [id, pose] : graph_->landmarkPoses()) landmarks.push_back({id, pose});
  const MapCorrectionParams& mc = params_.map_correction;
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  cov(0, 0) = cov(1, 1) = mc.landmark_sigma_xy_m * mc.landmark_sigma_xy_m;
  cov(2, 2) = mc.landmark_sigma_theta_rad * mc.landmark_sigma_theta_rad;
  // The particles move with the graph's correction at the newest measured
  // pose: the graph's estimate there against the filter's. The filter's
  // estimate at the graph's newest node (newer than the solve's, when it
  // ran in the background) moves with them.
  const Pose2 shift = solved_at.compose(filter_at.inverse());
  filter_.correctMap(landmarks, cov, shift);
  newest_graph_node_filter_ = shift.compose(newest_graph_node_filter_);
}

Observation Backend::alignedObservation(const MeasurementInput& m, const Pose2& then) const {
  // Move the measurement to the particles' time: y_now = y (+) D.
  const Pose2 d = then.between(history_.back().reading.pose);
  const Pose2& y = m.relative;
  Eigen::Matrix3d r = params_.filter.measurementCovariance();
  const double dist = std::hypot(y.x, y.y);
  r(0, 0) += std::pow(params_.measurement_sigma_xy_per_m * dist, 2);
  r(1, 1) += std::pow(params_.measurement_sigma_xy_per_m * dist, 2);
  r(2, 2) += std::pow(params_.measurement_sigma_theta_rad_per_m * dist, 2);
  PoseWithCovariance now(y, r);
  now.apply(d, filter_.params().motion.stepCovariance(d));
  Observation obs;
  obs.landmark_id = m.landmark_id;
  obs.utime = m.utime;
  obs.relative = now.pose();
  obs.covariance = now.covariance();
  return obs;
}

MeasurementResult Backend::addMeasurement(const MeasurementInput& m) {
  MeasurementResult result;
  result.status =
      prefilter({m.relative, m.proj_err_rms_px, m.num_points, m.slope}, params_.prefilter);
  ++counters_.status[static_cast<int>(result.status)];
  auto finish = [&](MeasurementUse use) {
    result.use = use;
    ++counters_.use[static_cast<int>(use)];
    return result;
  };
  if (result.status != MeasurementStatus::kAccepted) return finish(MeasurementUse::kRejected);
  if (m.landmark_id < 0) return finish(MeasurementUse::kInvalidLandmark);
  noteCamera(m.camera, m.utime);
  // (Not while kidnapped: as a solve on the update, a correction waits
  // for the filter to know where it is.)
  if (solving_.valid() && !filter_.kidnapped() && m.utime >= solving_result_utime_) takeSolution();

  MeasurementUse why = MeasurementUse::kUsed;
  const std::optional<OdometryAt> then_odometry =
      odometryAt(m.utime, params_.max_measurement_age_s, &why);
  if (!then_odometry) return finish(why);
  const Observation obs = alignedObservation(m, then_odometry->pose);
  if (graph_ && graph_->retired(m.landmark_id)) {
    // Badly built (PoseGraphParams::odometry_gate_*): not for the filter;
    // the graph keeps judging it, so it may come back.
    if (!filter_.kidnapped())
      addToGraph(m, *then_odometry,
                 filter_.outlierFraction(obs) <= params_.map_correction.max_outlier_fraction);
    return finish(MeasurementUse::kRetired);
  }
  // While the filter relocalizes a robot known to have been moved
  // (ParticleFilter::robotWasMoved), every measurement goes to it: it draws
  // all its particles anew from each (uniform weights, so correlated ones
  // count for nothing twice), and its recovery wants measurements of
  // distinct landmarks in a row, which one per landmark per
  // landmark_min_interval_s spreads over seconds (tuning home 49: 9.7 s
  // from a carry's detection to its recovery, five filter updates). Not
  // after a kidnapping that may be a repeated pattern's false alarm: its
  // look-alikes, measured at camera rate, would confirm a wrong
  // relocalization at once (tuning home 36).
  const bool relocalizing_moved_robot = filter_.kidnapped() && filter_.robotWasMoved();
  if (params_.landmark_min_interval_s > 0 && !relocalizing_moved_robot) {
    const auto last = last_used_.find(m.landmark_id);
    const auto min_us = static_cast<int64_t>(params_.landmark_min_interval_s * 1e6);
    if (last != last_used_.end() && m.utime >= last->second && m.utime - last->second < min_us) {
      // Not for the filter's weights, but for its kidnap test (a consistent
      // one ends a run of inconsistent ones); the pose graph models the
      // correlation (its measurement error grows with the distance) and may
      // take it, and the odometry calibration pairs it with the landmark's
      // other measurements.
      filter_.noteUnused(obs);
      if ((graph_ || calibration_) && !filter_.kidnapped()) {
        const double outliers = filter_.outlierFraction(obs);
        if (graph_)
          addToGraph(m, *then_odometry, outliers <= params_.map_correction.max_outlier_fraction);
        if (calibration_ && outliers <= kConsistentOutlierFraction &&
            !filter_.isLookAlike(m.landmark_id))
          calibrate(m, *then_odometry);
      }
      return finish(MeasurementUse::kThinned);
    }
    last_used_[m.landmark_id] = m.utime;
  }
  result.update = filter_.update(obs);
  const UpdateReport& u = result.update;
  counters_.landmarks_initialized += u.kind == UpdateKind::kInitialized;
  counters_.kidnaps_detected += u.kidnap_detected;
  counters_.recoveries += u.recovered;
  counters_.kidnaps_cancelled += u.cancelled;
  counters_.drift_corrections += u.drift_corrected;
  counters_.look_alike_measurements_ignored += u.kind == UpdateKind::kIgnored;
  counters_.resamplings += u.resampled;
  counters_.landmarks_moved_after_relocalization += u.moved;
  if (u.moved && graph_) {
    // Its creation node is where the robot was thought to be after it had
    // been moved: it would pull the graph there. The filter keeps it.
    graph_->removeLandmark(m.landmark_id);
    graph_last_used_.erase(m.landmark_id);
    landmark_drift_.erase(m.landmark_id);
  }
  if (u.drift_corrected && graph_ && filter_.recentlyRelocalizedAfterAMove(m.utime))
    moveRelocalizedSegment(m.utime, u.drift_shift);
  if (u.kidnap_detected) deferred_.clear();
  if (u.deferred) deferred_[m.landmark_id] = m;
  if (calibration_ && u.kidnap_detected) calibration_->breakOdometry();
  // Consistent: most particles found it within the gate.
  const bool consistent =
      !filter_.kidnapped() &&
      (u.kind == UpdateKind::kInitialized ||
       static_cast<double>(u.num_outliers) <=
           kConsistentOutlierFraction * static_cast<double>(filter_.particles().size()));
  if (calibration_ && consistent && !u.suspect) calibrate(m, *then_odometry);
  if (u.recovered) mapDeferredLandmarks();
  if (graph_) {
    if (u.recovered) result.join = joinOrBreakAfterKidnap();
    if (!filter_.kidnapped()) {
      addToGraph(m, *then_odometry,
                 u.kind == UpdateKind::kInitialized ||
                     static_cast<double>(u.num_outliers) <=
                         params_.map_correction.max_outlier_fraction *
                             static_cast<double>(filter_.particles().size()));
    }
  }
  return finish(MeasurementUse::kUsed);
}

double Backend::historySpanS() const {
  // The map correction places landmarks announced late: it needs more.
  return graph_ ? std::max(params_.max_measurement_age_s, params_.map_correction.creation_max_age_s)
                : params_.max_measurement_age_s;
}

void Backend::mapDeferredLandmarks() {
  const double keep_s = historySpanS();
  for (const auto& [id, m] : deferred_) {
    MeasurementUse why = MeasurementUse::kUsed;
    const std::optional<OdometryAt> then = odometryAt(m.utime, keep_s, &why);
    if (!then) continue;  // older than the odometry kept: mapped when next seen
    const UpdateReport u = filter_.update(alignedObservation(m, then->pose));
    counters_.landmarks_mapped_after_relocalization += u.kind == UpdateKind::kInitialized;
  }
  deferred_.clear();
}

void Backend::calibrate(const MeasurementInput& m, const OdometryAt& then) {
  if (!calibration_->add(m.landmark_id, m.utime, m.relative, then)) return;
  if (!params_.odometry_calibration.adopt) return;
  const OdometryNoiseEstimate e = calibration_->estimate();
  if (!e.valid) return;
  const MotionNoise noise = calibration_->adoptable(e);
  filter_.setMotionNoise(noise);
  if (graph_) graph_->setOdometryNoise(noise.sigma_translation, noise.sigma_rotation);
}

}  // namespace vslam::backend
