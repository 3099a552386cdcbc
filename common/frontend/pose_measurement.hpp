#pragma once
// The visual measurement of the vSLAM paper (Karlsson et al., section 4.2):
// the pose of the robot now relative to the robot at a landmark's creation,
// from 2-D/3-D correspondences between the current image and the landmark's
// 3-D structure, with the statistics the pre-filter judges it by (ProjErrRMS,
// NPoints, Slope), and the pre-filter itself (section 5). No LCM, no images:
// the stage adapter converts to and from vslam.visual_measurement_t.
//
// Frames ("a_T_b" is the pose of frame b in frame a):
//   creation robot  the robot base when the landmark was created (x forward,
//                   y left, z up); the landmark's 3-D points live here, so a
//                   landmark created by one camera can be measured by another.
//   current robot   the robot base now.
//   camera          the current camera (OpenCV: x right, y down, z optical
//                   axis), placed on the robot by robot_T_camera.
// The measurement is creation_T_current_robot, projected to the floor plane.
// docs/frontend.md ("Measurement") has the derivation, the reading of Slope
// and the measured speed.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <string>
#include <vector>

#include "backend/prefilter.hpp"
#include "config/robot_config.hpp"
#include "odometry/pose2.hpp"

namespace vslam::frontend {

// The current camera as the measurement needs it: focal lengths to express
// errors in pixels, and where the camera sits on the robot.
struct MeasurementCamera {
  double fx = 0;  // pixels
  double fy = 0;  // pixels
  Eigen::Isometry3d robot_T_camera = Eigen::Isometry3d::Identity();

  static MeasurementCamera fromConfig(const config::CameraConfig& camera);
};

// Minimal solver inside the RANSAC loop of cv::solvePnPRansac.
enum class PnpSolver { kAp3p, kP3p, kEpnp, kSqpnp };

struct PoseMeasurementParams {
  int min_correspondences = 6;  // fewer input pairs: kTooFewCorrespondences
  int min_inliers = 6;          // fewer inliers after RANSAC or refinement: kTooFewInliers
  PnpSolver solver = PnpSolver::kAp3p;
  double ransac_threshold_px = 3.0;  // inlier if reprojection error below, pixels
  double ransac_confidence = 0.99;
  int ransac_max_iterations = 200;
  double huber_px = 1.0;             // robust loss scale of the refinement, pixels
  double inlier_threshold_px = 3.0;  // re-selection of inliers after refinement, pixels
  int max_refinement_rounds = 3;     // refine, re-select, until the inlier set is stable
  int max_solver_iterations = 25;    // Ceres iterations per round
  double min_depth_m = 0.05;         // inliers closer to (or behind) the camera: diverged

  // Throws std::invalid_argument naming the first bad field.
  void validate() const;
};

enum class MeasurementFailure {
  kNone = 0,
  kInvalidInput,           // sizes differ, non-finite values, bad camera or params
  kTooFewCorrespondences,  // fewer than min_correspondences pairs given
  kRansacFailed,           // solvePnPRansac found no model
  kTooFewInliers,          // a model, but with fewer than min_inliers inliers
  kRefinementDiverged,     // Ceres failed, non-finite pose, or points behind the camera
};
const char* toString(MeasurementFailure f);

struct PoseMeasurement {
  // Paper's y = [dx, dy, dtheta]: the current robot in the creation robot's
  // frame, projected to the floor plane (x, y of the translation; yaw of the
  // rotation, i.e. the heading of the current robot's x axis in that plane).
  Pose2 relative;
  double proj_err_rms_px = 0;  // ProjErrRMS: RMS reprojection error over the inliers, pixels
  int num_points = 0;          // NPoints: inlier correspondences of the refined pose
  double slope = 0;            // Slope: tan of the estimated tilt of the robot (0 on a level floor)
  Eigen::Isometry3d creation_T_current_robot = Eigen::Isometry3d::Identity();

  // Diagnostics.
  std::vector<int> inliers;        // indices into the input correspondences, ascending
  int ransac_inliers = 0;          // inliers of the RANSAC model, before refinement
  int ransac_iteration_bound = 0;  // OpenCV's adaptive iteration bound for the RANSAC inlier ratio
  int refinement_rounds = 0;
  int solver_iterations = 0;  // Ceres iterations summed over rounds
  // Out-of-plane part of creation_T_current_robot (roll about x, then pitch
  // about y, then yaw about z: R = Rz(yaw) Ry(pitch) Rx(roll)); all ~0 on a
  // level floor, large values mean a bad measurement.
  double z_m = 0;
  double roll_rad = 0;
  double pitch_rad = 0;
  // Marginal standard deviations of dx, dy, dtheta from the Gauss-Newton
  // covariance of the refined 6-DOF pose with the residual variance
  // ProjErrRMS^2: how well the point set constrains the pose.
  double sigma_x_m = 0;
  double sigma_y_m = 0;
  double sigma_theta_rad = 0;
  double ransac_ms = 0;
  double refine_ms = 0;
  double total_ms = 0;
};

struct PoseMeasurementResult {
  MeasurementFailure failure = MeasurementFailure::kNone;
  std::string reason;           // human-readable detail when failed
  PoseMeasurement measurement;  // filled as far as the pipeline got
  bool ok() const { return failure == MeasurementFailure::kNone; }
};

// points_creation_robot[i] (metres, creation robot frame) is seen at
// observations_normalized[i], undistorted normalized coordinates (x/z, y/z)
// of the current camera. Outliers among the pairs are expected. Bad data
// is a failure with a reason; bad params throw std::invalid_argument.
PoseMeasurementResult measurePose(const std::vector<Eigen::Vector3d>& points_creation_robot,
                                  const std::vector<Eigen::Vector2d>& observations_normalized,
                                  const MeasurementCamera& camera,
                                  const PoseMeasurementParams& params);

// Planar projection of a 6-DOF robot pose (see PoseMeasurement::relative),
// and the out-of-plane remainder.
Pose2 planarPose(const Eigen::Isometry3d& a_T_b);
struct OutOfPlane {
  double z_m = 0, roll_rad = 0, pitch_rad = 0;
  double slope = 0;  // tan(angle between the two frames' z axes); +inf if tilted 90 deg or more
};
OutOfPlane outOfPlane(const Eigen::Isometry3d& a_T_b);

// ---------------------------------------------------------------------------
// Pre-filter (paper section 5): shared with the back-end, in backend/prefilter.hpp.
using backend::MeasurementStatus;
using backend::PrefilterParams;
using backend::toString;

// The first failed test in the paper's order (ProjErrRMS, NPoints, Slope);
// non-finite pose or statistics, or a negative count, are kRejectedInvalid.
MeasurementStatus prefilter(const PoseMeasurement& m, const PrefilterParams& params = {});

}  // namespace vslam::frontend
