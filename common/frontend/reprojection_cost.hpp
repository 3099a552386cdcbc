#pragma once
// Ceres reprojection residuals of the bundle adjustments (three-view
// creation, refinement from later views), in pixels.

#include <ceres/ceres.h>
#include <ceres/rotation.h>

#include <Eigen/Core>

namespace vslam::frontend {

// Reprojection residual in pixels of a point X (view-1 camera frame) seen
// at normalized coordinates (u, v) by a camera with X_k = R(aa) X + t:
// r = f (X_k.xy / X_k.z - (u, v)).
struct ReprojectionCost {
  ReprojectionCost(const Eigen::Vector2d& x, double f) : obs(x), focal(f) {}

  template <typename T>
  bool operator()(const T* angle_axis, const T* t, const T* point, T* residual) const {
    T q[3];
    ceres::AngleAxisRotatePoint(angle_axis, point, q);
    q[0] += t[0];
    q[1] += t[1];
    q[2] += t[2];
    residual[0] = T(focal) * (q[0] / q[2] - T(obs.x()));
    residual[1] = T(focal) * (q[1] / q[2] - T(obs.y()));
    return true;
  }

  static ceres::CostFunction* Create(const Eigen::Vector2d& x, double f) {
    return new ceres::AutoDiffCostFunction<ReprojectionCost, 2, 3, 3, 3>(
        new ReprojectionCost(x, f));
  }

  Eigen::Vector2d obs;
  double focal;
};

// The same for view 1 (identity pose): only the point is a parameter.
struct ReferenceReprojectionCost {
  ReferenceReprojectionCost(const Eigen::Vector2d& x, double f) : obs(x), focal(f) {}

  template <typename T>
  bool operator()(const T* point, T* residual) const {
    residual[0] = T(focal) * (point[0] / point[2] - T(obs.x()));
    residual[1] = T(focal) * (point[1] / point[2] - T(obs.y()));
    return true;
  }

  static ceres::CostFunction* Create(const Eigen::Vector2d& x, double f) {
    return new ceres::AutoDiffCostFunction<ReferenceReprojectionCost, 2, 3>(
        new ReferenceReprojectionCost(x, f));
  }

  Eigen::Vector2d obs;
  double focal;
};

// Solver options of the front-end's bundle adjustments: tens of points and a
// few views, solved on the calling thread, silently.
inline ceres::Solver::Options smallProblemOptions(int max_iterations) {
  ceres::Solver::Options options;
  options.linear_solver_type = ceres::DENSE_SCHUR;
  options.num_threads = 1;
  options.max_num_iterations = max_iterations;
  options.logging_type = ceres::SILENT;
  return options;
}

}  // namespace vslam::frontend
