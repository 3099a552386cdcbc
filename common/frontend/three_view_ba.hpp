#pragma once
// Three-view bundle adjustment with the paper's robust outlier rejection
// (section 4.1.3, "Refine the pose and structure estimates"). No LCM.

#include <Eigen/Geometry>
#include <cstdint>
#include <string>
#include <vector>

namespace vslam::frontend {

// Undistorted normalized coordinates of N points in the three views.
struct ThreeViewObservations {
  std::vector<Eigen::Vector2d> x1, x2, x3;
  size_t size() const { return x1.size(); }
};

// Motion and structure in the view-1 camera frame: X_k = cam_k_T_cam1 X.
struct ThreeViewModel {
  Eigen::Isometry3d cam2_T_cam1 = Eigen::Isometry3d::Identity();  // |t| = 1 (the gauge)
  Eigen::Isometry3d cam3_T_cam1 = Eigen::Isometry3d::Identity();
  std::vector<Eigen::Vector3d> points;  // one per observation, view-1 camera frame
};

struct ThreeViewBaParams {
  double huber_px = 1.0;        // Huber loss scale on each reprojection residual, pixels
  int max_iterations = 20;      // Levenberg-Marquardt iterations per solve
  int max_rounds = 5;           // solve-and-reject rounds
  double outlier_sigmas = 4.0;  // paper: drop points with any view's error > 4 robust stds
  double min_sigma_px = 0.1;    // floor of the robust std (noise-free data)
  double function_tolerance = 1e-7;
};

struct ThreeViewBaReport {
  bool converged = false;      // every solve ended usable and the model is finite
  int rounds = 0;              // solves run
  int iterations = 0;          // Levenberg-Marquardt iterations over all solves
  int num_points_in = 0;       // active points given
  int num_rejected = 0;        // dropped as outliers (incl. behind a camera)
  double initial_rms_px = 0;   // over the given points, before any solve
  double final_rms_px = 0;     // over the kept points
  double robust_sigma_px = 0;  // 1.4826 MAD of the residual components, last round
  std::string message;         // why not converged
};

// Minimises the reprojection error (pixels, Huber) of the active points over
// the 11 motion parameters (view 2: rotation + unit translation direction,
// view 3: rotation + translation; view 1 fixed at the identity) and 3N
// structure parameters, with Ceres (DENSE_SCHUR, one thread). After each
// solve, points whose error in any view exceeds outlier_sigmas x the robust
// std of all residual components, or that lie behind a camera, are
// deactivated and the problem is solved again, until none is dropped or
// max_rounds solves have run. `model` holds the initial guess and receives
// the result, rescaled to |t2| = 1 (inactive points are rescaled but not
// optimised); `active` (one flag per observation) is updated.
ThreeViewBaReport threeViewBundleAdjust(const ThreeViewObservations& obs, double focal_px,
                                        const ThreeViewBaParams& params, ThreeViewModel* model,
                                        std::vector<uint8_t>* active);

// Reprojection error (pixels) of point i in view k (0, 1, 2).
double reprojectionErrorPx(const ThreeViewObservations& obs, const ThreeViewModel& model,
                           double focal_px, size_t i, int view);
// RMS over the active points of the 2-D reprojection errors in all views.
double reprojectionRmsPx(const ThreeViewObservations& obs, const ThreeViewModel& model,
                         double focal_px, const std::vector<uint8_t>& active);

}  // namespace vslam::frontend
