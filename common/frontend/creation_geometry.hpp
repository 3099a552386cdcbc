#pragma once
// Geometry for three-view landmark creation (paper section 4.1.3), on
// undistorted normalized image coordinates (x/z, y/z). Camera poses are
// cam_T_ref: a point X in the reference (view-1 camera) frame is
// R X + t in the camera's frame, OpenCV's convention for recoverPose.

#include <Eigen/Geometry>
#include <cstdint>
#include <vector>

namespace vslam::frontend {

// Rotation matrix <-> angle-axis vector (axis times angle, radians).
Eigen::Vector3d angleAxisFromRotation(const Eigen::Matrix3d& rotation);
Eigen::Matrix3d rotationFromAngleAxis(const Eigen::Vector3d& angle_axis);

// Linear triangulation (DLT, smallest eigenvector of A^T A) of one point
// seen at normalized coordinates x[k] by cameras cam_T_ref[k], k < n.
// Returns false when the solution is at infinity or not finite; does not
// check the depth's sign.
bool triangulateDlt(const Eigen::Isometry3d* cam_T_ref, const Eigen::Vector2d* x, int n,
                    Eigen::Vector3d* point_ref);

// Median angle (radians) between the rays of x2 and the rays of x1 rotated
// by the best pure rotation (least squares over the rays, refitted once
// without residuals above three medians). Small when the camera only
// rotated: the parallax that translation creates, whatever the rotation.
double medianRotationOnlyResidual(const std::vector<Eigen::Vector2d>& x1,
                                  const std::vector<Eigen::Vector2d>& x2);

struct TwoViewParams {
  double threshold = 1.5 / 277.0;  // epipolar distance for RANSAC inliers, normalized units
  double confidence = 0.999;
  int max_iterations = 1000;
  // Refinement: Sampson error with a Huber loss of `threshold` over the
  // inliers, then inliers re-selected among all points; this many rounds.
  int refine_rounds = 2;
};

struct TwoViewResult {
  Eigen::Isometry3d cam2_T_cam1 = Eigen::Isometry3d::Identity();  // |t| = 1
  std::vector<uint8_t> inliers;                                   // per correspondence
  int ransac_inliers = 0;  // after RANSAC and the cheirality check
  int num_inliers = 0;     // after refinement
};

// Relative pose of two views up to scale: 5-point RANSAC essential matrix
// (cv::findEssentialMat with identity K), cv::recoverPose (cheirality), then
// Ceres refinement of rotation and unit translation on the Sampson error
// with inliers re-selected each round (paper: Longuet-Higgins, refined on
// the epipolar residual with robust outlier detection). False when there
// are fewer than 5 correspondences or no pose was found.
bool estimateTwoView(const std::vector<Eigen::Vector2d>& x1, const std::vector<Eigen::Vector2d>& x2,
                     const TwoViewParams& params, TwoViewResult* result);

// Sampson distance (normalized units) of x2^T E x1 for E = [t]x R.
double sampsonDistance(const Eigen::Isometry3d& cam2_T_cam1, const Eigen::Vector2d& x1,
                       const Eigen::Vector2d& x2);

// Standard deviation of a point's range along the view-1 ray when its
// image positions (pixels, focal length focal_px) have standard deviation
// sigma_px in each coordinate and the cameras are held fixed: sigma^2 u^T
// (J^T J)^-1 u, J the 2n x 3 Jacobian of the projections, u the ray. The
// paper's "rms reprojection error times the sensitivity of the 3-D point to
// the reprojection error". Infinity when J^T J is singular.
double rangeSigma(const Eigen::Vector3d& point_ref, const Eigen::Isometry3d* cam_T_ref, int n,
                  double focal_px, double sigma_px);

}  // namespace vslam::frontend
