#pragma once
// Ceres cost of the pose refinement in the visual measurement
// (pose_measurement.hpp): the reprojection error of one landmark point.
//
// Parameters: the pose camera_T_creation (creation robot frame -> current
// camera) as an angle-axis vector w (3) and a translation t (3, metres):
//   p = R(w) X + t            X: landmark point, creation robot frame
//   r = [fx (p_x / p_z - u),  (u, v): undistorted normalized observation
//        fy (p_y / p_z - v)]  pixels, so the robust loss and thresholds are
//                             in pixels.
// Derivatives by automatic differentiation: the problem has 6 parameters and
// tens of residuals, where autodiff costs little and cannot be wrong; the
// test compares them with central differences anyway.

#include <ceres/autodiff_cost_function.h>
#include <ceres/rotation.h>

#include <Eigen/Core>

namespace vslam::frontend {

// Not ReprojectionCost: that is the bundle adjustments' (reprojection_cost.hpp),
// and two classes of one name broke the one-definition rule (an
// AddressSanitizer build at -Og deleted this one with the other's size).
struct PoseReprojectionCost {
  PoseReprojectionCost(const Eigen::Vector3d& point, const Eigen::Vector2d& normalized, double fx,
                       double fy)
      : point_(point), normalized_(normalized), fx_(fx), fy_(fy) {}

  template <typename T>
  bool operator()(const T* const angle_axis, const T* const translation, T* residual) const {
    const T x[3] = {T(point_.x()), T(point_.y()), T(point_.z())};
    T p[3];
    ceres::AngleAxisRotatePoint(angle_axis, x, p);
    p[0] += translation[0];
    p[1] += translation[1];
    p[2] += translation[2];
    // A point at or behind the camera has no projection; the caller keeps
    // such points out of the problem, this only guards the division.
    if (!(p[2] > T(1e-9))) return false;
    residual[0] = T(fx_) * (p[0] / p[2] - T(normalized_.x()));
    residual[1] = T(fy_) * (p[1] / p[2] - T(normalized_.y()));
    return true;
  }

  static ceres::CostFunction* Create(const Eigen::Vector3d& point,
                                     const Eigen::Vector2d& normalized, double fx, double fy) {
    return new ceres::AutoDiffCostFunction<PoseReprojectionCost, 2, 3, 3>(
        new PoseReprojectionCost(point, normalized, fx, fy));
  }

 private:
  Eigen::Vector3d point_;
  Eigen::Vector2d normalized_;
  double fx_, fy_;
};

}  // namespace vslam::frontend
