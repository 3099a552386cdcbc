#include "frontend/frontend.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>

#include "util/log.hpp"

namespace vslam::frontend {
namespace {

// Odometry readings are kept for the time a landmark's first view may
// precede its creation (FrontendParams::max_view_span_s) and this margin for
// the landmark DB's answer, so that the landmarks made here and by the other
// cameras find their first view's odometry (anchorOf); at most this many.
constexpr double kOdometryHistoryMarginS = 10.0;
constexpr size_t kMaxOdometryReadings = 100000;
// A landmark's created_odometry is this front-end's odometry if they agree
// this closely at its created_utime (the same readings, interpolated alike).
constexpr double kSameOdometryM = 0.01;
constexpr double kSameOdometryRad = 0.01;

// The continuity test. First the thumbnails
// (FrontendParams::view_jump_min_thumbnail_similarity): the two frames
// reduced ten times, correlated over the horizontal shifts the odometry's
// turn allows. It needs no features, and a repeated pattern's features found
// again across a carry do not hide it. Generated homes 1180-1199 (60,000
// frames, both cameras): across each of their 11 carries at least one
// camera's frames correlated below 0.26, two carries (tiles: 6 and 11 % of
// the features found again) and one from a dim room facing a wall (under 40
// features) among them, while the frames the robot drove between correlated
// above 0.58 (0.1 % below 0.81) but for plain walls. A plain wall's
// thumbnail is flat, its correlation its noise's: under 4 grey levels of
// standard deviation in either frame it tells nothing (ten pairs of
// plain-wall frames of those homes, 0-5 features, correlated under 0.13).
// Nor where neither frame has kThumbnailMinFeatures: a view with next to no
// features is a plain surface whose thumbnail holds only its shading, which
// changes with the angle to the light (home 1197: two frames of 0 and 1
// features, 6-7 grey levels of shading, correlated 0.07 without a carry,
// and two false kidnappings followed). The dim room's carry of home 1190
// had 17 and 21. Thumbnails alike at least that but less than
// view_jump_features_below_similarity are unsure: carries between two
// views of one pattern correlated 0.40-0.71 (in one camera: generated homes
// 1273, 1290, 1310, 1315, 1325, 1337, whose features were not found again),
// so there the features are tested as well.
// Where the thumbnails cannot tell, the features
// (FrontendParams::view_jump_max_matched_share): the previous frame's
// strongest features, and its largest-scale ones, are
// looked for in the next one with a strict ratio test, so that few chance
// matches pass between unrelated views. Both: the motion blur of a fast turn
// can hide the fine features that are most of the strongest (generated homes
// 1026 and 1031, turns at 70-87 deg/s: 19 frames in two runs found under 5 %
// of their strongest features again but 12-32 % of their largest), while
// across a carry neither is found (12 carries in 20 homes: at most 2.5 %).
// Neither is tested across a gap in the frames, or where odometry says the
// robot moved or turned enough to see something else; the features not with
// too few to tell.
constexpr int kContinuityFeatures = 200;
constexpr int kContinuityMinFeatures = 40;
constexpr double kContinuityRatio = 0.6;
constexpr double kContinuityMaxGapS = 1.0;
constexpr double kContinuityMaxTravelM = 0.3;
constexpr double kContinuityMaxTurnRad = 0.5;
constexpr int kThumbnailShiftMarginPx = 2;
constexpr double kThumbnailFlatLevel = 4.0;   // grey levels
constexpr size_t kThumbnailMinFeatures = 10;  // in one of the two frames

double msSince(Utime start) { return 1e-3 * static_cast<double>(monotonicUtime() - start); }

// The descriptors of the kContinuityFeatures features that `before` puts first.
template <typename Before>
cv::Mat bestDescriptors(const Features& f, Before before) {
  std::vector<int> order(f.size());
  std::iota(order.begin(), order.end(), 0);
  const size_t keep = std::min(order.size(), static_cast<size_t>(kContinuityFeatures));
  std::partial_sort(order.begin(), order.begin() + static_cast<std::ptrdiff_t>(keep), order.end(),
                    [&](int a, int b) {
                      return before(f.keypoints[static_cast<size_t>(a)],
                                    f.keypoints[static_cast<size_t>(b)]);
                    });
  cv::Mat d(static_cast<int>(keep), 128, CV_32F);
  for (size_t i = 0; i < keep; ++i) f.descriptors.row(order[i]).copyTo(d.row(static_cast<int>(i)));
  return d;
}

}  // namespace

LandmarkModel NewLandmark::model(int64_t id) const {
  LandmarkModel model;
  model.id = id;
  model.created_utime = first_view.utime;
  model.created_odometry = first_view.odometry;
  model.points_robot = landmark.points_robot;
  model.descriptors.create(static_cast<int>(landmark.feature_index.size()), 128, CV_32F);
  for (size_t i = 0; i < landmark.feature_index.size(); ++i) {
    first_view.features.descriptors.row(landmark.feature_index[i])
        .copyTo(model.descriptors.row(static_cast<int>(i)));
  }
  return model;
}

Frontend::Frontend(FrontendParams params)
    : params_(std::move(params)),
      extractor_(params_.camera, params_.sift),
      creator_(params_.camera, params_.creation),
      measurement_camera_(MeasurementCamera::fromConfig(params_.camera)),
      index_(params_.recognition),
      refining_matcher_(MatchParams{params_.recognition.ratio, false}),
      continuity_matcher_(MatchParams{kContinuityRatio, false}) {
  params_.refinement.validate();
}

Frontend::OdometryVerdict Frontend::addOdometry(Utime t, const Pose2& pose) {
  if (!pose.isFinite()) return OdometryVerdict::kNotFinite;
  std::lock_guard<std::mutex> lock(odometry_mutex_);
  if (!odometry_.empty() && t <= odometry_.back().first) return OdometryVerdict::kNotNewer;
  OdometryAt at{pose, 0, 0};
  if (!odometry_.empty()) {
    const OdometryAt& last = odometry_.back().second;
    const Pose2 step = last.pose.between(pose);
    at.distance_m = last.distance_m + std::hypot(step.x, step.y);
    at.rotation_rad = last.rotation_rad + std::abs(step.theta);
  }
  odometry_.emplace_back(t, at);
  const Utime keep = static_cast<Utime>((params_.max_view_span_s + kOdometryHistoryMarginS) *
                                        static_cast<double>(kMicrosPerSecond));
  while (odometry_.size() > kMaxOdometryReadings || t - odometry_.front().first > keep) {
    odometry_.pop_front();
  }
  return OdometryVerdict::kAdded;
}

bool Frontend::odometryAt(Utime t, Pose2* pose) const {
  const auto at = odometryWithTotalsAt(t);
  if (at) *pose = at->pose;
  return at.has_value();
}

std::optional<OdometryAt> Frontend::odometryWithTotalsAt(Utime t) const {
  std::lock_guard<std::mutex> lock(odometry_mutex_);
  if (odometry_.empty()) return std::nullopt;
  const auto after = std::lower_bound(odometry_.begin(), odometry_.end(), t,
                                      [](const auto& a, Utime v) { return a.first < v; });
  if (after == odometry_.end()) {
    if (t - odometry_.back().first > params_.max_odometry_gap) return std::nullopt;
    return odometry_.back().second;
  }
  if (after == odometry_.begin() || after->first == t) {
    if (after->first - t > params_.max_odometry_gap) return std::nullopt;
    return after->second;
  }
  const auto before = std::prev(after);
  const double s =
      static_cast<double>(t - before->first) / static_cast<double>(after->first - before->first);
  return interpolateOdometry(before->second, after->second, s);
}

std::optional<Frontend::Anchor> Frontend::anchorOf(const LandmarkModel& model) const {
  if (params_.coverage_gate.sigmas <= 0 || model.created_utime <= 0) return std::nullopt;
  const auto at = odometryWithTotalsAt(model.created_utime);
  if (!at) return std::nullopt;
  const Pose2 d = at->pose.between(model.created_odometry);
  if (std::hypot(d.x, d.y) > kSameOdometryM || std::abs(d.theta) > kSameOdometryRad) {
    return std::nullopt;
  }
  return Anchor{model.created_utime, *at};
}

void Frontend::extract(const cv::Mat& gray, Features* out) { extractor_.extract(gray, out); }

FrameResult Frontend::track(Utime t, Features features) {
  FrameResult result;
  View view;
  view.utime = t;
  view.features = std::move(features);
  const std::optional<OdometryAt> odometry = odometryWithTotalsAt(t);
  result.have_odometry = odometry.has_value();
  if (odometry) view.odometry = odometry->pose;

  // First whether the view jumped: the robot may have been carried, and the
  // odometry then tells nothing of where the landmarks made before are.
  if (params_.view_jump_max_matched_share > 0 || params_.view_jump_min_thumbnail_similarity > 0) {
    const Utime t1 = monotonicUtime();
    testContinuity(t, view, result.have_odometry, &result);
    result.continuity_ms = msSince(t1);
  }

  Utime t0 = monotonicUtime();
  std::vector<Recognition> recognized;
  std::vector<std::optional<OdometryAt>> anchors;
  {
    std::lock_guard<std::mutex> lock(index_mutex_);
    if (result.view_jumped) {
      anchors_.clear();
      anchor_epoch_ = t;
    }
    recognized = index_.recognize(view.features);
    for (const auto& r : recognized) {
      const auto it = anchors_.find(r.landmark_id);
      anchors.push_back(it == anchors_.end() ? std::nullopt : std::optional(it->second.odometry));
    }
  }
  result.recognitions = static_cast<int>(recognized.size());
  result.recognition_ms = msSince(t0);

  t0 = monotonicUtime();
  int measured = 0;
  for (size_t i = 0; i < recognized.size(); ++i) {
    const Recognition& r = recognized[i];
    if (measured >= params_.max_measurements_per_frame) break;
    const auto pose =
        measurePose(r.points_robot, r.observations, measurement_camera_, params_.measurement);
    if (!pose.ok()) {
      ++result.measurement_failures;
      continue;
    }
    const PoseMeasurement& pm = pose.measurement;
    const bool near_creation =
        params_.coverage_radius_m <= 0 ||
        std::hypot(pm.relative.x, pm.relative.y) <= params_.coverage_radius_m;
    if (near_creation && prefilter(pm, params_.prefilter) == MeasurementStatus::kAccepted) {
      const auto& anchor = anchors[i];
      if (anchor && odometry &&
          !odometryAgrees(pm.relative, *anchor, *odometry, params_.coverage_gate)) {
        ++result.odometry_disagreements;
      } else {
        result.place_covered = true;
      }
    }
    if (r.landmark_id >= kFirstPendingId) continue;
    result.measurements.push_back({r.landmark_id, pm});
    ++measured;
  }
  result.measurement_ms = msSince(t0);

  t0 = monotonicUtime();
  if (result.have_odometry && !refining_.empty()) {
    observeRefining(view.features, view.odometry);
    refineDue(t, view.odometry, &result);
  }
  if (result.have_odometry) considerCreation(std::move(view), &result);
  result.creation_ms = msSince(t0);
  return result;
}

void Frontend::testContinuity(Utime t, const View& view, bool have_odometry, FrameResult* result) {
  const Features& f = view.features;
  if (previous_ && toSeconds(t - previous_->utime) <= kContinuityMaxGapS) {
    bool near = true;
    double turn_rad = kContinuityMaxTurnRad;
    if (have_odometry && previous_->have_odometry) {
      const Pose2 d = previous_->odometry.between(view.odometry);
      turn_rad = std::abs(d.theta);
      near = std::hypot(d.x, d.y) <= kContinuityMaxTravelM && turn_rad <= kContinuityMaxTurnRad;
    }
    if (near) {
      result->previous_utime = previous_->utime;
      if (params_.view_jump_min_thumbnail_similarity > 0 &&
          std::max(static_cast<size_t>(previous_->strongest.rows), f.size()) >=
              kThumbnailMinFeatures) {
        // Thumbnail pixels the turn moves the view by, and a margin for the
        // travel's parallax.
        const int max_shift = static_cast<int>(
            std::ceil(turn_rad * params_.camera.fx / kThumbnailScale) + kThumbnailShiftMarginPx);
        result->thumbnail_similarity =
            thumbnailSimilarity(previous_->thumbnail, f.thumbnail, max_shift, kThumbnailFlatLevel);
        result->view_jumped =
            result->thumbnail_similarity < params_.view_jump_min_thumbnail_similarity;
      }
      // Features decide where the thumbnails cannot, and have a say where
      // they are not sure.
      const bool thumbnails_unsure =
          std::isnan(result->thumbnail_similarity) ||
          (!result->view_jumped &&
           result->thumbnail_similarity < params_.view_jump_features_below_similarity);
      if (params_.view_jump_max_matched_share > 0 && thumbnails_unsure &&
          previous_->strongest.rows >= kContinuityMinFeatures &&
          static_cast<int>(f.size()) >= kContinuityMinFeatures) {
        auto share_found = [&](const cv::Mat& previous) {
          std::vector<cv::DMatch> matches;
          continuity_matcher_.match(previous, f.descriptors, &matches);
          return static_cast<double>(matches.size()) / static_cast<double>(previous.rows);
        };
        result->matched_share =
            std::max(share_found(previous_->strongest), share_found(previous_->largest));
        result->view_jumped = result->matched_share < params_.view_jump_max_matched_share;
      }
    }
  }
  PreviousFrame p;
  p.utime = t;
  p.have_odometry = have_odometry;
  p.odometry = view.odometry;
  p.thumbnail = f.thumbnail;
  p.strongest = bestDescriptors(
      f, [](const cv::KeyPoint& a, const cv::KeyPoint& b) { return a.response > b.response; });
  p.largest = bestDescriptors(
      f, [](const cv::KeyPoint& a, const cv::KeyPoint& b) { return a.size > b.size; });
  previous_ = std::move(p);
}

void Frontend::considerCreation(View view, FrameResult* result) {
  // A place a known landmark already measures well needs no new one.
  if (result->place_covered) {
    views_.clear();
    return;
  }
  while (!views_.empty() &&
         toSeconds(view.utime - views_.front().utime) > params_.max_view_span_s) {
    views_.pop_front();
  }
  if (!views_.empty()) {
    const Pose2 d = views_.back().odometry.between(view.odometry);
    if (std::hypot(d.x, d.y) < params_.creation_baseline_m) return;
  }
  views_.push_back(std::move(view));
  if (views_.size() < 3) return;

  const std::array<Pose2, 3> odometry = {views_[0].odometry, views_[1].odometry,
                                         views_[2].odometry};
  auto made = creator_.create(views_[0].features, views_[1].features, views_[2].features, odometry);
  if (!made.ok()) {
    log::debug("no landmark from views at ", views_[0].utime, ": ", made.reason);
    result->creation_failure = made.reason;
    views_.pop_front();  // slide: the next view may make a better triple
    return;
  }
  result->created = NewLandmark{std::move(views_[0]), std::move(made.landmark)};
  views_.clear();
  if (params_.refine_distance_m > 0) {
    RefiningLandmark refining;
    refining.made = *result->created;
    refining.model = refining.made.model(0);
    refining.creation_odometry = odometry;
    refining.last_view = odometry[2];
    refining.path_end = odometry[2];
    refining_.push_back(std::move(refining));
  }
}

void Frontend::observeRefining(const Features& features, const Pose2& odometry) {
  std::vector<cv::DMatch> matches;
  std::vector<Eigen::Vector3d> points;
  std::vector<Eigen::Vector2d> observations;
  for (auto& refining : refining_) {
    refining_matcher_.match(refining.model.descriptors, features.descriptors, &matches);
    if (static_cast<int>(matches.size()) < params_.recognition.min_matches) continue;
    points.clear();
    observations.clear();
    for (const auto& m : matches) {
      points.push_back(refining.model.points_robot[static_cast<size_t>(m.queryIdx)]);
      observations.push_back(features.normalized[static_cast<size_t>(m.trainIdx)]);
    }
    const auto pose = measurePose(points, observations, measurement_camera_, params_.measurement);
    if (!pose.ok() ||
        prefilter(pose.measurement, params_.prefilter) != MeasurementStatus::kAccepted)
      continue;
    LaterView view;
    view.odometry = odometry;
    view.robot1_T_robot = pose.measurement.creation_T_current_robot;
    for (int i : pose.measurement.inliers) {
      view.points.push_back(matches[static_cast<size_t>(i)].queryIdx);
      view.observations.push_back(observations[static_cast<size_t>(i)]);
    }
    const Pose2 d = refining.last_view.between(odometry);
    if (std::hypot(d.x, d.y) < params_.creation_baseline_m) {
      refining.newest = std::move(view);
      continue;
    }
    refining.later.push_back(std::move(view));
    refining.newest.reset();
    refining.last_view = odometry;
  }
}

void Frontend::refineDue(Utime t, const Pose2& odometry, FrameResult* result) {
  for (auto& refining : refining_) {
    const Pose2 step = refining.path_end.between(odometry);
    refining.path_m += std::hypot(step.x, step.y);
    refining.path_end = odometry;
  }
  for (auto it = refining_.begin(); it != refining_.end(); ++it) {
    const Pose2 from_first = it->creation_odometry[0].between(odometry);
    const bool due = std::hypot(from_first.x, from_first.y) >= params_.refine_distance_m ||
                     it->path_m >= 2 * params_.refine_distance_m ||
                     toSeconds(t - it->made.first_view.utime) > params_.max_view_span_s;
    if (!due) continue;
    if (it->newest) it->later.push_back(std::move(*it->newest));
    FrameResult::Refined refined;
    refined.report =
        refineLandmark(it->creation_odometry, it->later, creator_.focalPx(),
                       creator_.robotTCamera(), params_.refinement, &it->made.landmark);
    if (!refined.report.refined) {
      log::debug("landmark from views at ", it->made.first_view.utime,
                 " not refined: ", refined.report.reason);
    }
    refined.landmark = std::move(it->made);
    result->refined = std::move(refined);
    refining_.erase(it);
    return;  // one per frame: the others are due at the next
  }
}

void Frontend::addLandmark(LandmarkModel model) {
  const auto anchor = anchorOf(model);
  std::lock_guard<std::mutex> lock(index_mutex_);
  const auto it = anchors_.find(model.id);
  // A landmark sent again (its structure refined) keeps its anchor, though
  // its first view's odometry may be forgotten by now.
  const bool same = it != anchors_.end() && it->second.created_utime == model.created_utime;
  if (!same) {
    if (anchor && model.created_utime >= anchor_epoch_) {
      anchors_[model.id] = *anchor;
    } else if (it != anchors_.end()) {
      anchors_.erase(it);
    }
  }
  index_.add(std::move(model));
}

void Frontend::removeLandmark(int64_t id) {
  std::lock_guard<std::mutex> lock(index_mutex_);
  anchors_.erase(id);
  index_.remove(id);
}

size_t Frontend::numLandmarks() const {
  std::lock_guard<std::mutex> lock(index_mutex_);
  return index_.size();
}

}  // namespace vslam::frontend
