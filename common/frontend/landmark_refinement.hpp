#pragma once
// Refinement of a new landmark's structure from later views (beyond the
// paper). The creation's three views are 20 cm apart, so a point 3 m away
// is triangulated from a 40 cm baseline and its metric scale comes from 40
// cm of odometry; the errors that leaves grow with the distance the landmark
// is measured from (docs/benchmark-homes.md). Views of the same points from
// farther along the path (up to a metre, say) are a longer baseline for both:
// one bundle adjustment over the three creation views and the later ones,
// with the later views' odometry as a prior on their positions, which fixes
// the scale with all of the odometry rather than the first 40 cm. No LCM.

#include <Eigen/Geometry>
#include <array>
#include <string>
#include <vector>

#include "frontend/landmark_creation.hpp"
#include "odometry/pose2.hpp"

namespace vslam::frontend {

// A view after the creation's three in which the landmark was recognized.
struct LaterView {
  Pose2 odometry;                             // the robot's odometry pose at the view
  Eigen::Isometry3d robot1_T_robot;           // vision's pose of the robot (initial guess)
  std::vector<int> points;                    // landmark point indices (rows of points_robot)
  std::vector<Eigen::Vector2d> observations;  // their features, normalized coordinates
};

struct RefinementParams {
  double huber_px = 1.0;    // Huber loss scale on each reprojection residual, pixels
  int max_iterations = 30;  // Levenberg-Marquardt iterations per solve
  int max_rounds = 3;       // solve-and-reject rounds
  double outlier_sigmas =
      4.0;                    // a later view's observation beyond this x the robust std is dropped
  double min_sigma_px = 0.1;  // floor of the robust std
  // Std of a view's odometry position relative to view 1: the per-sqrt-metre
  // part times the square root of the distance, plus the floor (metres).
  double odometry_sigma_per_sqrt_m = 0.03;
  double odometry_sigma_floor_m = 0.005;
  // Nothing is refined unless a later view with at least min_observations
  // points is this far (robot position) from view 1.
  double min_span_m = 0.5;  // the creation's views span 0.4 m
  int min_observations = 10;
  double max_rms_px = 2.0;  // reprojection RMS after the solve above this: not refined

  void validate() const;  // throws std::invalid_argument naming the field
};

struct RefinementReport {
  bool refined = false;
  std::string reason;                          // why not, when not refined
  int later_views = 0;                         // views used beyond the creation's three
  int later_observations = 0;                  // their observations used
  int rejected_observations = 0;               // of those, dropped as outliers
  double span_m = 0;                           // farthest view's odometry distance from view 1
  double rms_before_px = 0, rms_after_px = 0;  // over every view's observations kept
  double scale_change = 1;                     // median over points of new range / old range
  double median_point_shift_m = 0;             // median distance a point moved
};

// Refines `landmark` (as LandmarkCreator made it from views with the
// odometry `creation_odometry`) with the later views. On success the points
// and the views' camera poses are replaced and report.refined is true;
// otherwise the landmark is left as it was and report.reason says why.
RefinementReport refineLandmark(const std::array<Pose2, 3>& creation_odometry,
                                const std::vector<LaterView>& later, double focal_px,
                                const Eigen::Isometry3d& robot_T_camera,
                                const RefinementParams& params, CreatedLandmark* landmark);

}  // namespace vslam::frontend
