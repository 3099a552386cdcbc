#pragma once
// Three-view landmark creation (paper section 4.1): three-way SIFT
// correspondences, two-view motion and relative scale, three-view bundle
// adjustment with robust outlier rejection, depth-uncertainty selection,
// metric scale from odometry, structure in the robot frame. No LCM.

#include <Eigen/Geometry>
#include <array>
#include <string>
#include <vector>

#include "config/robot_config.hpp"
#include "frontend/features.hpp"
#include "frontend/matching.hpp"
#include "frontend/three_view_ba.hpp"
#include "odometry/pose2.hpp"

namespace vslam::frontend {

struct CreationParams {
  MatchParams match;       // ratio 0.8 (Lowe), not mutual
  int min_three_way = 20;  // fewer consistent three-way matches: kTooFewMatches
  // Two-view RANSAC (5-point essential matrix): epipolar distance threshold
  // in pixels (divided by the focal length for normalized coordinates).
  double ransac_threshold_px = 1.5;
  double ransac_confidence = 0.999;
  int ransac_max_iterations = 1000;
  int min_two_view_inliers = 15;  // per pair after refinement, else kTooFewMatches
  // Median parallax left after the best pure rotation, pixels, in views 1-2
  // and 1-3; below it the camera only rotated (or stood still) and depth is
  // unobservable: kDegenerateMotion. Pixel noise alone gives ~1.7 x the
  // per-view, per-coordinate std (0.83 px at 0.5 px); 20 cm forward at
  // 1-5 m gives several pixels.
  double min_parallax_px = 1.5;
  // Odometry distance between the camera positions of views 1 and 2 needed
  // to fix the metric scale, metres; below: kDegenerateMotion.
  double min_baseline_m = 0.05;
  ThreeViewBaParams ba;     // Huber 1 px, 4 robust stds, up to 5 rounds
  double max_rms_px = 2.0;  // reprojection RMS after the BA above this: kBaDiverged
  // Depth uncertainty (see docs/frontend.md): per point, the std of its range
  // along the view-1 ray from the BA's point Jacobian with the cameras held
  // fixed, for a pixel std estimated from the BA residuals (at least
  // sigma_floor_px). A point is kept when its range std is at most
  // max_depth_sigma_m AND at most max_relative_depth_sigma x its range.
  double sigma_floor_px = 0.1;
  double max_depth_sigma_m = 0.10;  // paper: points with depth uncertainty > 10 cm removed
  double max_relative_depth_sigma = 0.05;
  int min_good_points = 20;  // paper: typically 30-70 points with good structure

  void validate() const;  // throws std::invalid_argument naming the field
};

enum class CreationStatus {
  kOk,
  kTooFewMatches,     // too few three-way matches or two-view inliers
  kDegenerateMotion,  // no parallax (pure rotation, standing still) or no odometry baseline
  kBaDiverged,        // the bundle adjustment failed or left a large reprojection error
  kTooFewGoodPoints,  // too few points left after outlier rejection and uncertainty selection
};
const char* toString(CreationStatus status);

struct CreationDiagnostics {
  std::array<int, 3> num_features{};                               // per view (create() only)
  int num_matches_12 = 0, num_matches_13 = 0, num_matches_23 = 0;  // ratio-test matches
  int num_three_way = 0;
  double parallax_12_px = 0, parallax_13_px = 0;  // median rotation-compensated parallax
  int ransac_inliers_12 = 0, ransac_inliers_13 = 0;
  int inliers_12 = 0, inliers_13 = 0;  // after the Sampson refinement
  double relative_scale = 0;           // |t13| / |t12| from the median depth ratio
  int ba_points = 0;                   // points entering the BA
  int ba_rejected = 0;                 // outliers the BA dropped
  int ba_rounds = 0, ba_iterations = 0;
  double ba_initial_rms_px = 0, ba_final_rms_px = 0, robust_sigma_px = 0;
  double pixel_sigma_px = 0;  // per-coordinate image noise std used for depth uncertainty
  int num_uncertain = 0;      // BA inliers dropped for depth uncertainty
  double odometry_baseline_12_m = 0, odometry_baseline_13_m = 0;
  double metric_scale = 0;  // metres per unit |t12|
  // Vision's |c13| / |c12| against odometry's: 1 when they agree.
  double baseline_ratio_agreement = 0;
  double ms_matching = 0, ms_two_view = 0, ms_bundle_adjustment = 0, ms_total = 0;
};

struct CreatedLandmark {
  // 3-D points in the robot frame at view 1 (x forward, y left, z up; metres).
  std::vector<Eigen::Vector3d> points_robot;
  // For each point: its index in view 1's Features (keypoint and descriptor).
  std::vector<int> feature_index;
  std::vector<double> range_sigma_m;  // std of each point's range from the view-1 camera
  // Each point's feature in views 1, 2 and 3, normalized coordinates (what a
  // refinement from later views needs: landmark_refinement.hpp).
  std::array<std::vector<Eigen::Vector2d>, 3> observations;
  double rms_reprojection_px = 0;  // over the kept points in all three views
  int num_three_way = 0;
  // The cameras of views 2 and 3 as estimated by vision, in the view-1 robot
  // frame, metric.
  Eigen::Isometry3d robot1_T_camera2 = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d robot1_T_camera3 = Eigen::Isometry3d::Identity();
};

struct CreationResult {
  CreationStatus status = CreationStatus::kTooFewMatches;
  std::string reason;  // human-readable, empty when ok
  CreatedLandmark landmark;
  CreationDiagnostics diagnostics;
  bool ok() const { return status == CreationStatus::kOk; }
};

class LandmarkCreator {
 public:
  // focal_px converts pixel thresholds to normalized units; robot_T_camera
  // is the camera's mounting (OpenCV camera frame in the robot base frame).
  LandmarkCreator(double focal_px, const Eigen::Isometry3d& robot_T_camera,
                  const CreationParams& params = {});
  LandmarkCreator(const config::CameraConfig& camera, const CreationParams& params = {});

  // Three views in time order with the robot's odometry pose (any fixed
  // odometry frame) at each.
  CreationResult create(const Features& view1, const Features& view2, const Features& view3,
                        const std::array<Pose2, 3>& odometry);

  // From given three-way correspondences (normalized coordinates);
  // feature_index[i] is copied to the output for the points kept.
  CreationResult createFromCorrespondences(const ThreeViewObservations& obs,
                                           const std::vector<int>& feature_index,
                                           const std::array<Pose2, 3>& odometry);

  const CreationParams& params() const { return params_; }
  double focalPx() const { return focal_px_; }
  const Eigen::Isometry3d& robotTCamera() const { return robot_T_camera_; }

 private:
  void solve(const ThreeViewObservations& obs, const std::vector<int>& feature_index,
             const std::array<Pose2, 3>& odometry, CreationResult* result);

  double focal_px_;
  Eigen::Isometry3d robot_T_camera_;
  CreationParams params_;
  RatioMatcher matcher_;
  std::vector<cv::DMatch> m12_, m13_, m23_;
  std::vector<Triplet> triplets_;
};

// Lifts a planar robot pose to 3-D (rotation about z, z = 0).
Eigen::Isometry3d isometryFromPose2(const Pose2& pose);

}  // namespace vslam::frontend
