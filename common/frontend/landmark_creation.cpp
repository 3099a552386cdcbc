#include "frontend/landmark_creation.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "frontend/creation_geometry.hpp"
#include "util/statistics.hpp"

namespace vslam::frontend {

namespace {

using Clock = std::chrono::steady_clock;

double msSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

void require(bool condition, const char* field, const char* what) {
  if (!condition) throw std::invalid_argument(std::string("CreationParams.") + field + " " + what);
}

std::string format(const std::string& text, double value) {
  std::ostringstream os;
  os.precision(3);
  os << text << value;
  return os.str();
}

}  // namespace

void CreationParams::validate() const {
  require(match.ratio > 0 && match.ratio <= 1, "match.ratio", "must be in (0, 1]");
  require(min_three_way >= 6, "min_three_way", "must be at least 6");
  require(ransac_threshold_px > 0, "ransac_threshold_px", "must be positive");
  require(ransac_confidence > 0 && ransac_confidence < 1, "ransac_confidence", "must be in (0, 1)");
  require(ransac_max_iterations > 0, "ransac_max_iterations", "must be positive");
  require(min_two_view_inliers >= 5, "min_two_view_inliers", "must be at least 5");
  require(min_parallax_px >= 0, "min_parallax_px", "must not be negative");
  require(min_baseline_m > 0, "min_baseline_m", "must be positive");
  require(ba.huber_px > 0, "ba.huber_px", "must be positive");
  require(ba.max_iterations > 0, "ba.max_iterations", "must be positive");
  require(ba.max_rounds > 0, "ba.max_rounds", "must be positive");
  require(ba.outlier_sigmas > 0, "ba.outlier_sigmas", "must be positive");
  require(ba.min_sigma_px > 0, "ba.min_sigma_px", "must be positive");
  require(max_rms_px > 0, "max_rms_px", "must be positive");
  require(sigma_floor_px >= 0, "sigma_floor_px", "must not be negative");
  require(max_depth_sigma_m > 0, "max_depth_sigma_m", "must be positive");
  require(max_relative_depth_sigma > 0, "max_relative_depth_sigma", "must be positive");
  require(min_good_points >= 3, "min_good_points", "must be at least 3");
}

const char* toString(CreationStatus status) {
  switch (status) {
    case CreationStatus::kOk:
      return "ok";
    case CreationStatus::kTooFewMatches:
      return "too few matches";
    case CreationStatus::kDegenerateMotion:
      return "degenerate motion";
    case CreationStatus::kBaDiverged:
      return "bundle adjustment diverged";
    case CreationStatus::kTooFewGoodPoints:
      return "too few good points";
  }
  return "unknown";
}

Eigen::Isometry3d isometryFromPose2(const Pose2& pose) {
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.linear() = Eigen::AngleAxisd(pose.theta, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  t.translation() = Eigen::Vector3d(pose.x, pose.y, 0.0);
  return t;
}

LandmarkCreator::LandmarkCreator(double focal_px, const Eigen::Isometry3d& robot_T_camera,
                                 const CreationParams& params)
    : focal_px_(focal_px),
      robot_T_camera_(robot_T_camera),
      params_(params),
      matcher_(params.match) {
  if (!(focal_px_ > 0))
    throw std::invalid_argument("LandmarkCreator: focal length must be positive");
  params_.validate();
}

LandmarkCreator::LandmarkCreator(const config::CameraConfig& camera, const CreationParams& params)
    : LandmarkCreator(0.5 * (camera.fx + camera.fy), camera.robot_T_camera, params) {}

CreationResult LandmarkCreator::create(const Features& view1, const Features& view2,
                                       const Features& view3,
                                       const std::array<Pose2, 3>& odometry) {
  const auto start = Clock::now();
  CreationResult result;
  auto& diag = result.diagnostics;
  diag.num_features = {static_cast<int>(view1.size()), static_cast<int>(view2.size()),
                       static_cast<int>(view3.size())};
  // Paper 4.1.2: train on view 1, match views 2 and 3; train on view 2,
  // match view 3. Queries here are the earlier view, so each match maps a
  // feature of the earlier view to one of the later view.
  matcher_.match(view1.descriptors, view2.descriptors, &m12_);
  matcher_.match(view1.descriptors, view3.descriptors, &m13_);
  matcher_.match(view2.descriptors, view3.descriptors, &m23_);
  threeWayMatches(m12_, m13_, m23_, &triplets_);
  diag.num_matches_12 = static_cast<int>(m12_.size());
  diag.num_matches_13 = static_cast<int>(m13_.size());
  diag.num_matches_23 = static_cast<int>(m23_.size());

  ThreeViewObservations obs;
  std::vector<int> feature_index;
  obs.x1.reserve(triplets_.size());
  obs.x2.reserve(triplets_.size());
  obs.x3.reserve(triplets_.size());
  feature_index.reserve(triplets_.size());
  for (const Triplet& t : triplets_) {
    obs.x1.push_back(view1.normalized.at(t.i1));
    obs.x2.push_back(view2.normalized.at(t.i2));
    obs.x3.push_back(view3.normalized.at(t.i3));
    feature_index.push_back(t.i1);
  }
  diag.ms_matching = msSince(start);
  solve(obs, feature_index, odometry, &result);
  diag.ms_total = msSince(start);
  return result;
}

CreationResult LandmarkCreator::createFromCorrespondences(const ThreeViewObservations& obs,
                                                          const std::vector<int>& feature_index,
                                                          const std::array<Pose2, 3>& odometry) {
  if (obs.x2.size() != obs.size() || obs.x3.size() != obs.size() ||
      feature_index.size() != obs.size())
    throw std::invalid_argument("createFromCorrespondences: sizes differ");
  const auto start = Clock::now();
  CreationResult result;
  solve(obs, feature_index, odometry, &result);
  result.diagnostics.ms_total = msSince(start);
  return result;
}

namespace {

// One landmark's creation from its three-way matches, step by step (paper
// 4.1.2, (a)-(h)): the state the steps share, and a step each. A step that
// returns false has recorded in the result why no landmark was created.
class CreationSteps {
 public:
  CreationSteps(const ThreeViewObservations& obs, const CreationParams& params, double focal_px,
                const Eigen::Isometry3d& robot_T_camera, CreationResult* result)
      : obs_(obs),
        params_(params),
        focal_px_(focal_px),
        robot_T_camera_(robot_T_camera),
        result_(result),
        diag_(result->diagnostics),
        n_(obs.size()) {
    diag_.num_three_way = static_cast<int>(n_);
    result_->landmark.num_three_way = static_cast<int>(n_);
  }

  // (a) enough three-way matches.
  bool enoughMatches() {
    if (static_cast<int>(n_) >= params_.min_three_way) return true;
    return fail(CreationStatus::kTooFewMatches,
                format("three-way matches below the minimum " +
                           std::to_string(params_.min_three_way) + ": ",
                       static_cast<double>(n_)));
  }

  // Odometry baselines of the camera (not the robot centre: the camera is
  // mounted off-centre, so turning moves it).
  bool cameraMoved(const std::array<Pose2, 3>& odometry) {
    const Eigen::Isometry3d world_T_cam[3] = {isometryFromPose2(odometry[0]) * robot_T_camera_,
                                              isometryFromPose2(odometry[1]) * robot_T_camera_,
                                              isometryFromPose2(odometry[2]) * robot_T_camera_};
    diag_.odometry_baseline_12_m =
        (world_T_cam[1].translation() - world_T_cam[0].translation()).norm();
    diag_.odometry_baseline_13_m =
        (world_T_cam[2].translation() - world_T_cam[0].translation()).norm();
    if (diag_.odometry_baseline_12_m < params_.min_baseline_m) {
      return fail(
          CreationStatus::kDegenerateMotion,
          format("odometry: the camera moved less than min_baseline_m between views 1 and 2: m=",
                 diag_.odometry_baseline_12_m));
    }
    return true;
  }

  // Parallax that no rotation explains: zero for pure rotation.
  bool enoughParallax() {
    two_view_start_ = Clock::now();
    diag_.parallax_12_px = focal_px_ * medianRotationOnlyResidual(obs_.x1, obs_.x2);
    diag_.parallax_13_px = focal_px_ * medianRotationOnlyResidual(obs_.x1, obs_.x3);
    if (!(diag_.parallax_12_px >= params_.min_parallax_px) ||
        !(diag_.parallax_13_px >= params_.min_parallax_px)) {
      return fail(CreationStatus::kDegenerateMotion,
                  format("no parallax (pure rotation or no motion): median px, views 1-2 ",
                         diag_.parallax_12_px) +
                      format(", views 1-3 ", diag_.parallax_13_px));
    }
    return true;
  }

  // (b) two-view motion up to scale for 1-2 and 1-3.
  bool twoViewMotions() {
    TwoViewParams two_view;
    two_view.threshold = params_.ransac_threshold_px / focal_px_;
    two_view.confidence = params_.ransac_confidence;
    two_view.max_iterations = params_.ransac_max_iterations;
    const bool ok12 = estimateTwoView(obs_.x1, obs_.x2, two_view, &r12_);
    const bool ok13 = estimateTwoView(obs_.x1, obs_.x3, two_view, &r13_);
    diag_.ransac_inliers_12 = r12_.ransac_inliers;
    diag_.ransac_inliers_13 = r13_.ransac_inliers;
    diag_.inliers_12 = r12_.num_inliers;
    diag_.inliers_13 = r13_.num_inliers;
    if (ok12 && ok13 && r12_.num_inliers >= params_.min_two_view_inliers &&
        r13_.num_inliers >= params_.min_two_view_inliers)
      return true;
    return fail(
        CreationStatus::kTooFewMatches,
        format("too few correspondences fit an epipolar geometry: views 1-2 ", r12_.num_inliers) +
            format(", views 1-3 ", r13_.num_inliers));
  }

  // (c) relative scale |t13| / |t12|: both two-view solutions have unit
  // translation, so a point's depth from 1-2 over its depth from 1-3 is the
  // ratio of the true baselines (paper: inverse of the median depth ratio).
  // Marks the points inlying in both pairs active.
  bool relativeScale() {
    active_.assign(n_, 0);
    std::vector<double> ratios;
    ratios.reserve(n_);
    for (size_t i = 0; i < n_; ++i) {
      if (!r12_.inliers[i] || !r13_.inliers[i]) continue;
      active_[i] = 1;
      const Eigen::Isometry3d c12[2] = {kIdentity, r12_.cam2_T_cam1};
      const Eigen::Isometry3d c13[2] = {kIdentity, r13_.cam2_T_cam1};
      const Eigen::Vector2d a[2] = {obs_.x1[i], obs_.x2[i]};
      const Eigen::Vector2d b[2] = {obs_.x1[i], obs_.x3[i]};
      Eigen::Vector3d p12, p13;
      if (triangulateDlt(c12, a, 2, &p12) && triangulateDlt(c13, b, 2, &p13) && p12.z() > 0 &&
          p13.z() > 0)
        ratios.push_back(p12.z() / p13.z());
    }
    if (ratios.size() < 5) {
      return fail(CreationStatus::kDegenerateMotion,
                  format("too few points triangulate in both pairs for the relative scale: ",
                         static_cast<double>(ratios.size())));
    }
    diag_.relative_scale = upperMedian(&ratios);
    return true;
  }

  // (d) initial structure: DLT over the three views; a point stays active
  // if it lies in front of all three cameras.
  bool initialStructure() {
    model_.cam2_T_cam1 = r12_.cam2_T_cam1;
    model_.cam3_T_cam1 = r13_.cam2_T_cam1;
    model_.cam3_T_cam1.translation() *= diag_.relative_scale;
    model_.points.assign(n_, Eigen::Vector3d(0, 0, 1));
    const Eigen::Isometry3d cams[3] = {kIdentity, model_.cam2_T_cam1, model_.cam3_T_cam1};
    for (size_t i = 0; i < n_; ++i) {
      if (!active_[i]) continue;
      const Eigen::Vector2d x[3] = {obs_.x1[i], obs_.x2[i], obs_.x3[i]};
      Eigen::Vector3d p;
      active_[i] = triangulateDlt(cams, x, 3, &p) && p.z() > 0 && (cams[1] * p).z() > 0 &&
                   (cams[2] * p).z() > 0;
      if (active_[i]) model_.points[i] = p;
    }
    diag_.ms_two_view = msSince(two_view_start_);
    diag_.ba_points = static_cast<int>(std::count(active_.begin(), active_.end(), 1));
    if (diag_.ba_points >= params_.min_good_points) return true;
    return fail(
        CreationStatus::kTooFewGoodPoints,
        format("too few points triangulate in front of all three cameras: ", diag_.ba_points));
  }

  // (e) three-view bundle adjustment with robust outlier rejection.
  bool bundleAdjust() {
    const auto ba_start = Clock::now();
    ba_ = threeViewBundleAdjust(obs_, focal_px_, params_.ba, &model_, &active_);
    diag_.ms_bundle_adjustment = msSince(ba_start);
    diag_.ba_rejected = ba_.num_rejected;
    diag_.ba_rounds = ba_.rounds;
    diag_.ba_iterations = ba_.iterations;
    diag_.ba_initial_rms_px = ba_.initial_rms_px;
    diag_.ba_final_rms_px = ba_.final_rms_px;
    diag_.robust_sigma_px = ba_.robust_sigma_px;
    if (!ba_.converged)
      return fail(CreationStatus::kBaDiverged, "bundle adjustment: " + ba_.message);
    if (!(ba_.final_rms_px <= params_.max_rms_px)) {
      return fail(CreationStatus::kBaDiverged,
                  format("reprojection RMS after the bundle adjustment above max_rms_px: ",
                         ba_.final_rms_px));
    }
    return true;
  }

  // (g) metric scale: least squares over both odometry baselines,
  // minimising (s |c2| - d12)^2 + (s |c3| - d13)^2 (camera centres c).
  void metricScale() {
    const double v12 = model_.cam2_T_cam1.inverse().translation().norm();
    const double v13 = model_.cam3_T_cam1.inverse().translation().norm();
    const double d12 = diag_.odometry_baseline_12_m, d13 = diag_.odometry_baseline_13_m;
    scale_ = (v12 * d12 + v13 * d13) / (v12 * v12 + v13 * v13);
    diag_.metric_scale = scale_;
    diag_.baseline_ratio_agreement = (v13 / v12) / (d13 / d12);
  }

  // (f) depth uncertainty, (h) robot frame: the landmark's points with a
  // small depth uncertainty, and its views' poses, in metres in the robot
  // frame of view 1.
  bool keepCertainPoints(const std::vector<int>& feature_index) {
    const double sigma_px = pixelSigma();
    const Eigen::Isometry3d ba_cams[3] = {kIdentity, model_.cam2_T_cam1, model_.cam3_T_cam1};
    auto& lm = result_->landmark;
    std::vector<uint8_t> good(n_, 0);
    for (size_t i = 0; i < n_; ++i) {
      if (!active_[i]) continue;
      const double range_sigma =
          scale_ * rangeSigma(model_.points[i], ba_cams, 3, focal_px_, sigma_px);
      const double range = scale_ * model_.points[i].norm();
      if (!(range_sigma <= params_.max_depth_sigma_m) ||
          !(range_sigma <= params_.max_relative_depth_sigma * range)) {
        ++diag_.num_uncertain;
        continue;
      }
      good[i] = 1;
      lm.points_robot.push_back(robot_T_camera_ * (scale_ * model_.points[i]));
      lm.feature_index.push_back(feature_index[i]);
      lm.range_sigma_m.push_back(range_sigma);
      lm.observations[0].push_back(obs_.x1[i]);
      lm.observations[1].push_back(obs_.x2[i]);
      lm.observations[2].push_back(obs_.x3[i]);
    }
    lm.rms_reprojection_px = reprojectionRmsPx(obs_, model_, focal_px_, good);
    lm.robot1_T_camera2 = metricRobotTCamera(model_.cam2_T_cam1);
    lm.robot1_T_camera3 = metricRobotTCamera(model_.cam3_T_cam1);
    if (static_cast<int>(lm.points_robot.size()) >= params_.min_good_points) return true;
    return fail(CreationStatus::kTooFewGoodPoints,
                format("points with small depth uncertainty below min_good_points " +
                           std::to_string(params_.min_good_points) + ": ",
                       static_cast<double>(lm.points_robot.size())));
  }

 private:
  bool fail(CreationStatus status, const std::string& reason) {
    result_->status = status;
    result_->reason = reason;
    return false;
  }

  // Per-coordinate pixel std from the BA residuals, unbiased for the
  // 3N + 11 parameters fitted to 6N residuals: rms of the 2-D errors (3N of
  // them) times sqrt(3N / (3N - 11)).
  double pixelSigma() {
    const double num_obs = 3.0 * std::count(active_.begin(), active_.end(), 1);
    const double sigma_px =
        std::max(ba_.final_rms_px * std::sqrt(num_obs / std::max(1.0, num_obs - 11.0)),
                 params_.sigma_floor_px);
    diag_.pixel_sigma_px = sigma_px;
    return sigma_px;
  }

  // A view's camera in the robot frame of view 1, in metres.
  Eigen::Isometry3d metricRobotTCamera(const Eigen::Isometry3d& cam_T_cam1) const {
    Eigen::Isometry3d cam1_T_cam = cam_T_cam1.inverse();
    cam1_T_cam.translation() *= scale_;
    return robot_T_camera_ * cam1_T_cam;
  }

  inline static const Eigen::Isometry3d kIdentity = Eigen::Isometry3d::Identity();

  const ThreeViewObservations& obs_;
  const CreationParams& params_;
  const double focal_px_;
  const Eigen::Isometry3d& robot_T_camera_;
  CreationResult* result_;
  CreationDiagnostics& diag_;
  const size_t n_;
  Clock::time_point two_view_start_;
  TwoViewResult r12_, r13_;
  std::vector<uint8_t> active_;  // per match: still a candidate point
  ThreeViewModel model_;
  ThreeViewBaReport ba_;
  double scale_ = 0;  // metres per unit of the model
};

}  // namespace

void LandmarkCreator::solve(const ThreeViewObservations& obs, const std::vector<int>& feature_index,
                            const std::array<Pose2, 3>& odometry, CreationResult* result) {
  CreationSteps steps(obs, params_, focal_px_, robot_T_camera_, result);
  if (!steps.enoughMatches() || !steps.cameraMoved(odometry) || !steps.enoughParallax() ||
      !steps.twoViewMotions() || !steps.relativeScale() || !steps.initialStructure() ||
      !steps.bundleAdjust())
    return;
  steps.metricScale();
  if (!steps.keepCertainPoints(feature_index)) return;
  result->status = CreationStatus::kOk;
  result->reason.clear();
}

}  // namespace vslam::frontend
