#include "frontend/pose_measurement.hpp"

#include <ceres/ceres.h>

#include <Eigen/Cholesky>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <stdexcept>

#include "frontend/measurement_cost.hpp"
#include "util/angles.hpp"

namespace vslam::frontend {
namespace {

using Clock = std::chrono::steady_clock;

double msSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

int cvFlag(PnpSolver s) {
  switch (s) {
    case PnpSolver::kAp3p:
      return cv::SOLVEPNP_AP3P;
    case PnpSolver::kP3p:
      return cv::SOLVEPNP_P3P;
    case PnpSolver::kEpnp:
      return cv::SOLVEPNP_EPNP;
    case PnpSolver::kSqpnp:
      return cv::SOLVEPNP_SQPNP;
  }
  return cv::SOLVEPNP_AP3P;
}

// Sample size of OpenCV's RANSAC kernel for the flag (4 for the P3P family,
// 5 otherwise).
int ransacSampleSize(PnpSolver s) {
  return (s == PnpSolver::kAp3p || s == PnpSolver::kP3p) ? 4 : 5;
}

// The adaptive iteration bound OpenCV's RANSAC stops at for an inlier ratio:
// log(1 - confidence) / log(1 - ratio^sample), capped at max_iterations.
int ransacIterationBound(double inlier_ratio, int sample, double confidence, int max_iterations) {
  const double good = std::pow(std::clamp(inlier_ratio, 0.0, 1.0), sample);
  if (good >= 1.0) return 1;
  const double num = std::log(std::max(1.0 - confidence, 1e-300));
  const double den = std::log(1.0 - good);
  if (!(den < 0) || num / den >= max_iterations) return max_iterations;
  return std::max(1, static_cast<int>(std::lround(num / den)));
}

// Squared reprojection error of every pair in pixels^2; +inf for points
// closer than min_depth to the camera (or behind it).
void squaredErrors(const Eigen::Isometry3d& camera_T_creation,
                   const std::vector<Eigen::Vector3d>& points,
                   const std::vector<Eigen::Vector2d>& obs, const MeasurementCamera& cam,
                   double min_depth, std::vector<double>& out) {
  out.resize(points.size());
  for (size_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector3d p = camera_T_creation * points[i];
    if (!(p.z() >= min_depth)) {
      out[i] = std::numeric_limits<double>::infinity();
      continue;
    }
    const double ex = cam.fx * (p.x() / p.z() - obs[i].x());
    const double ey = cam.fy * (p.y() / p.z() - obs[i].y());
    out[i] = ex * ex + ey * ey;
  }
}

Eigen::Isometry3d fromAngleAxis(const double* w, const double* t) {
  const Eigen::Vector3d wv(w[0], w[1], w[2]);
  const double angle = wv.norm();
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  if (angle > 0) T.linear() = Eigen::AngleAxisd(angle, wv / angle).toRotationMatrix();
  T.translation() = Eigen::Vector3d(t[0], t[1], t[2]);
  return T;
}

bool isFinite(const Eigen::Isometry3d& T) { return T.matrix().allFinite(); }

// creation_T_current * (rotation by w, translation v): a right perturbation
// of the robot pose in the current robot's frame (first order in (w, v)).
Eigen::Isometry3d perturbRight(const Eigen::Isometry3d& creation_T_current,
                               const Eigen::Matrix<double, 6, 1>& d) {
  Eigen::Isometry3d delta = Eigen::Isometry3d::Identity();
  const Eigen::Vector3d w = d.head<3>();
  if (w.norm() > 0) delta.linear() = Eigen::AngleAxisd(w.norm(), w.normalized()).toRotationMatrix();
  delta.translation() = d.tail<3>();
  return creation_T_current * delta;
}

// Marginal standard deviations of (dx, dy, dtheta): covariance of a right
// perturbation of the robot pose sigma^2 (J^T J)^-1 from the residual
// Jacobian J over the inliers (central differences), mapped through the
// Jacobian of the planar projection. sigma^2 = sum r^2 / (2n - 6), the
// unbiased per-coordinate residual variance.
void planarSigmas(const Eigen::Isometry3d& creation_T_current, const MeasurementCamera& cam,
                  const std::vector<Eigen::Vector3d>& points,
                  const std::vector<Eigen::Vector2d>& obs, const std::vector<int>& inliers,
                  double sum_sq, PoseMeasurement& m) {
  const int n = static_cast<int>(inliers.size());
  const double inf = std::numeric_limits<double>::infinity();
  m.sigma_x_m = m.sigma_y_m = m.sigma_theta_rad = inf;
  if (n < 4) return;
  const Eigen::Isometry3d camera_T_robot = cam.robot_T_camera.inverse();
  auto residuals = [&](const Eigen::Matrix<double, 6, 1>& d, Eigen::VectorXd& r) {
    const Eigen::Isometry3d camera_T_creation =
        camera_T_robot * perturbRight(creation_T_current, d).inverse();
    for (int k = 0; k < n; ++k) {
      const Eigen::Vector3d p = camera_T_creation * points[inliers[k]];
      r[2 * k] = cam.fx * (p.x() / p.z() - obs[inliers[k]].x());
      r[2 * k + 1] = cam.fy * (p.y() / p.z() - obs[inliers[k]].y());
    }
  };
  constexpr double h = 1e-6;
  Eigen::MatrixXd J(2 * n, 6);
  Eigen::Matrix<double, 3, 6> P;
  Eigen::VectorXd rp(2 * n), rm(2 * n);
  for (int j = 0; j < 6; ++j) {
    Eigen::Matrix<double, 6, 1> d = Eigen::Matrix<double, 6, 1>::Zero();
    d[j] = h;
    residuals(d, rp);
    const Pose2 pp = planarPose(perturbRight(creation_T_current, d));
    d[j] = -h;
    residuals(d, rm);
    const Pose2 pm = planarPose(perturbRight(creation_T_current, d));
    J.col(j) = (rp - rm) / (2 * h);
    P.col(j) << (pp.x - pm.x) / (2 * h), (pp.y - pm.y) / (2 * h),
        wrapAngle(pp.theta - pm.theta) / (2 * h);
  }
  const Eigen::Matrix<double, 6, 6> info = J.transpose() * J;
  const Eigen::LDLT<Eigen::Matrix<double, 6, 6>> ldlt(info);
  if (ldlt.info() != Eigen::Success || !ldlt.isPositive() ||
      ldlt.vectorD().minCoeff() <= 1e-12 * std::max(1.0, ldlt.vectorD().maxCoeff()))
    return;
  const double var = sum_sq / std::max(1, 2 * n - 6);
  const Eigen::Matrix<double, 6, 6> cov = var * ldlt.solve(Eigen::Matrix<double, 6, 6>::Identity());
  const Eigen::Matrix3d planar = P * cov * P.transpose();
  m.sigma_x_m = std::sqrt(std::max(0.0, planar(0, 0)));
  m.sigma_y_m = std::sqrt(std::max(0.0, planar(1, 1)));
  m.sigma_theta_rad = std::sqrt(std::max(0.0, planar(2, 2)));
}

}  // namespace

MeasurementCamera MeasurementCamera::fromConfig(const config::CameraConfig& camera) {
  MeasurementCamera c;
  c.fx = camera.fx;
  c.fy = camera.fy;
  c.robot_T_camera = camera.robot_T_camera;
  return c;
}

void PoseMeasurementParams::validate() const {
  auto bad = [](const char* field) {
    throw std::invalid_argument(std::string("PoseMeasurementParams.") + field + " out of range");
  };
  if (min_correspondences < 4) bad("min_correspondences");
  if (min_inliers < 4) bad("min_inliers");
  if (!(ransac_threshold_px > 0)) bad("ransac_threshold_px");
  if (!(ransac_confidence > 0 && ransac_confidence < 1)) bad("ransac_confidence");
  if (ransac_max_iterations < 1) bad("ransac_max_iterations");
  if (!(huber_px > 0)) bad("huber_px");
  if (!(inlier_threshold_px > 0)) bad("inlier_threshold_px");
  if (max_refinement_rounds < 1) bad("max_refinement_rounds");
  if (max_solver_iterations < 1) bad("max_solver_iterations");
  if (!(min_depth_m > 0)) bad("min_depth_m");
}

const char* toString(MeasurementFailure f) {
  switch (f) {
    case MeasurementFailure::kNone:
      return "ok";
    case MeasurementFailure::kInvalidInput:
      return "invalid input";
    case MeasurementFailure::kTooFewCorrespondences:
      return "too few correspondences";
    case MeasurementFailure::kRansacFailed:
      return "RANSAC failed";
    case MeasurementFailure::kTooFewInliers:
      return "too few inliers";
    case MeasurementFailure::kRefinementDiverged:
      return "refinement diverged";
  }
  return "unknown";
}

Pose2 planarPose(const Eigen::Isometry3d& a_T_b) {
  const Eigen::Matrix3d& R = a_T_b.linear();
  return {a_T_b.translation().x(), a_T_b.translation().y(),
          wrapAngle(std::atan2(R(1, 0), R(0, 0)))};
}

OutOfPlane outOfPlane(const Eigen::Isometry3d& a_T_b) {
  const Eigen::Matrix3d& R = a_T_b.linear();
  OutOfPlane o;
  o.z_m = a_T_b.translation().z();
  o.pitch_rad = std::asin(std::clamp(-R(2, 0), -1.0, 1.0));
  o.roll_rad = std::atan2(R(2, 1), R(2, 2));
  // b's z axis in a is R.col(2); its tilt from a's z axis has cosine R(2,2).
  const double horizontal = std::hypot(R(0, 2), R(1, 2));
  o.slope = R(2, 2) > 0 ? horizontal / R(2, 2) : std::numeric_limits<double>::infinity();
  return o;
}

namespace {

// One measurement, step by step: the state the steps share, and a step each.
// A step that returns false has recorded in the result why it failed.
class MeasurementSteps {
 public:
  MeasurementSteps(const std::vector<Eigen::Vector3d>& points_creation_robot,
                   const std::vector<Eigen::Vector2d>& observations_normalized,
                   const MeasurementCamera& camera, const PoseMeasurementParams& params,
                   Clock::time_point t0)
      : points_(points_creation_robot),
        obs_(observations_normalized),
        camera_(camera),
        params_(params),
        t0_(t0),
        n_(static_cast<int>(points_.size())) {}

  // Sizes agree, the camera and every correspondence are finite, and there
  // are enough of them.
  bool validInput() {
    if (points_.size() != obs_.size())
      return fail(MeasurementFailure::kInvalidInput, "points and observations differ in size (" +
                                                         std::to_string(points_.size()) + " vs " +
                                                         std::to_string(obs_.size()) + ")");
    if (!(camera_.fx > 0 && camera_.fy > 0 && std::isfinite(camera_.fx) &&
          std::isfinite(camera_.fy) && isFinite(camera_.robot_T_camera)))
      return fail(MeasurementFailure::kInvalidInput, "camera focal length or extrinsics invalid");
    for (size_t i = 0; i < points_.size(); ++i)
      if (!points_[i].allFinite() || !obs_[i].allFinite())
        return fail(MeasurementFailure::kInvalidInput,
                    "non-finite correspondence " + std::to_string(i));
    if (n_ < params_.min_correspondences)
      return fail(MeasurementFailure::kTooFewCorrespondences,
                  std::to_string(n_) + " correspondences, need " +
                      std::to_string(params_.min_correspondences));
    return true;
  }

  // (1) RANSAC PnP. Image points are the normalized coordinates scaled by the
  // focal lengths (pixel offsets from the principal point) with K =
  // diag(fx, fy, 1) and no distortion: the same geometry as normalized
  // coordinates with an identity K, but OpenCV's threshold is then exactly
  // ransac_threshold_px.
  bool ransacPnp() {
    cv::Mat object(n_, 3, CV_64F), image(n_, 2, CV_64F);
    for (int i = 0; i < n_; ++i) {
      for (int k = 0; k < 3; ++k) object.at<double>(i, k) = points_[i][k];
      image.at<double>(i, 0) = camera_.fx * obs_[i].x();
      image.at<double>(i, 1) = camera_.fy * obs_[i].y();
    }
    const cv::Matx33d K(camera_.fx, 0, 0, 0, camera_.fy, 0, 0, 0, 1);
    bool found = false;
    try {
      found = cv::solvePnPRansac(
          object, image, K, cv::noArray(), rvec_, tvec_, false, params_.ransac_max_iterations,
          static_cast<float>(params_.ransac_threshold_px), params_.ransac_confidence,
          ransac_inliers_, cvFlag(params_.solver));
    } catch (const cv::Exception& e) {
      m_.ransac_ms = msSince(t0_);
      return fail(MeasurementFailure::kRansacFailed,
                  std::string("solvePnPRansac threw: ") + e.what());
    }
    m_.ransac_ms = msSince(t0_);
    m_.ransac_inliers = static_cast<int>(ransac_inliers_.size());
    m_.ransac_iteration_bound = ransacIterationBound(
        static_cast<double>(m_.ransac_inliers) / n_, ransacSampleSize(params_.solver),
        params_.ransac_confidence, params_.ransac_max_iterations);
    if (!found || rvec_.empty() || tvec_.empty() || ransac_inliers_.empty())
      return fail(MeasurementFailure::kRansacFailed, "solvePnPRansac found no pose");
    if (m_.ransac_inliers < params_.min_inliers)
      return fail(MeasurementFailure::kTooFewInliers,
                  "RANSAC: " + std::to_string(m_.ransac_inliers) + " inliers, need " +
                      std::to_string(params_.min_inliers));
    return true;
  }

  // (2) Refinement: Levenberg-Marquardt on the 6-DOF camera_T_creation over
  // the inliers with a Huber loss, then re-select inliers among all pairs by
  // reprojection error; repeat while the inlier set changes.
  bool refine() {
    const Clock::time_point t_refine = Clock::now();
    startFromRansac();
    const double max_sq = params_.inlier_threshold_px * params_.inlier_threshold_px;
    ceres::Solver::Options options;
    options.linear_solver_type = ceres::DENSE_QR;
    options.max_num_iterations = params_.max_solver_iterations;
    options.num_threads = 1;
    options.logging_type = ceres::SILENT;
    options.minimizer_progress_to_stdout = false;
    for (int round = 0; round < params_.max_refinement_rounds; ++round) {
      if (static_cast<int>(inliers_.size()) < params_.min_inliers) break;
      ceres::Problem::Options problem_options;
      problem_options.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
      ceres::HuberLoss loss(params_.huber_px);
      ceres::Problem problem(problem_options);
      for (int i : inliers_)
        problem.AddResidualBlock(
            PoseReprojectionCost::Create(points_[i], obs_[i], camera_.fx, camera_.fy), &loss, w_,
            t_);
      ceres::Solver::Summary summary;
      ceres::Solve(options, &problem, &summary);
      ++m_.refinement_rounds;
      m_.solver_iterations += static_cast<int>(summary.iterations.size());
      const Eigen::Isometry3d camera_T_creation = fromAngleAxis(w_, t_);
      if (!summary.IsSolutionUsable() || !isFinite(camera_T_creation)) {
        m_.refine_ms = msSince(t_refine);
        return fail(MeasurementFailure::kRefinementDiverged, "Ceres: " + summary.message);
      }
      squaredErrors(camera_T_creation, points_, obs_, camera_, params_.min_depth_m, sq_);
      std::vector<int> reselected;
      for (int i = 0; i < n_; ++i)
        if (sq_[i] < max_sq) reselected.push_back(i);
      const bool stable = reselected == inliers_;
      inliers_.swap(reselected);
      if (stable) break;
    }
    m_.refine_ms = msSince(t_refine);
    return enoughRefinedInliers();
  }

  // (3) Robot pose now in the creation robot's frame:
  //   creation_T_camera = camera_T_creation^-1
  //   creation_T_current_robot = creation_T_camera * camera_T_robot,
  // and (4) its statistics.
  void poseAndStatistics() {
    const Eigen::Isometry3d camera_T_creation = fromAngleAxis(w_, t_);
    m_.creation_T_current_robot = camera_T_creation.inverse() * camera_.robot_T_camera.inverse();
    m_.relative = planarPose(m_.creation_T_current_robot);
    const OutOfPlane o = outOfPlane(m_.creation_T_current_robot);
    m_.z_m = o.z_m;
    m_.roll_rad = o.roll_rad;
    m_.pitch_rad = o.pitch_rad;

    const int num_inliers = static_cast<int>(inliers_.size());
    double sum_sq = 0;
    for (int i : inliers_) sum_sq += sq_[i];
    m_.inliers = inliers_;
    m_.num_points = num_inliers;
    m_.proj_err_rms_px = std::sqrt(sum_sq / num_inliers);
    m_.slope = o.slope;
    planarSigmas(m_.creation_T_current_robot, camera_, points_, obs_, inliers_, sum_sq, m_);
    m_.total_ms = msSince(t0_);
  }

  const PoseMeasurementResult& result() const { return result_; }

 private:
  bool fail(MeasurementFailure f, std::string reason) {
    result_.failure = f;
    result_.reason = std::move(reason);
    m_.total_ms = msSince(t0_);
    return false;
  }

  // The RANSAC pose, and of its inliers those that it puts in front of the
  // camera (the cost cannot be evaluated behind it).
  void startFromRansac() {
    rvec_.convertTo(rvec_, CV_64F);
    tvec_.convertTo(tvec_, CV_64F);
    for (int k = 0; k < 3; ++k) {
      w_[k] = rvec_.at<double>(k);
      t_[k] = tvec_.at<double>(k);
    }
    squaredErrors(fromAngleAxis(w_, t_), points_, obs_, camera_, params_.min_depth_m, sq_);
    for (int i : ransac_inliers_)
      if (std::isfinite(sq_[i])) inliers_.push_back(i);
    std::sort(inliers_.begin(), inliers_.end());
  }

  bool enoughRefinedInliers() {
    const int num_inliers = static_cast<int>(inliers_.size());
    // A refinement that loses most of the RANSAC consensus has left the basin
    // RANSAC found: report it as divergence, not as a weak measurement.
    if (2 * num_inliers < m_.ransac_inliers)
      return fail(MeasurementFailure::kRefinementDiverged,
                  "refinement kept " + std::to_string(num_inliers) + " of " +
                      std::to_string(m_.ransac_inliers) + " RANSAC inliers");
    if (num_inliers < params_.min_inliers)
      return fail(MeasurementFailure::kTooFewInliers, "refinement: " + std::to_string(num_inliers) +
                                                          " inliers, need " +
                                                          std::to_string(params_.min_inliers));
    return true;
  }

  const std::vector<Eigen::Vector3d>& points_;
  const std::vector<Eigen::Vector2d>& obs_;
  const MeasurementCamera& camera_;
  const PoseMeasurementParams& params_;
  const Clock::time_point t0_;
  const int n_;
  PoseMeasurementResult result_;
  PoseMeasurement& m_ = result_.measurement;
  cv::Mat rvec_, tvec_;  // RANSAC's camera_T_creation
  std::vector<int> ransac_inliers_;
  double w_[3] = {}, t_[3] = {};  // camera_T_creation as angle-axis and translation
  std::vector<int> inliers_;
  std::vector<double> sq_;  // squared reprojection error of every pair, pixels^2
};

}  // namespace

PoseMeasurementResult measurePose(const std::vector<Eigen::Vector3d>& points_creation_robot,
                                  const std::vector<Eigen::Vector2d>& observations_normalized,
                                  const MeasurementCamera& camera,
                                  const PoseMeasurementParams& params) {
  const Clock::time_point t0 = Clock::now();
  params.validate();
  MeasurementSteps steps(points_creation_robot, observations_normalized, camera, params, t0);
  if (steps.validInput() && steps.ransacPnp() && steps.refine()) steps.poseAndStatistics();
  return steps.result();
}

MeasurementStatus prefilter(const PoseMeasurement& m, const PrefilterParams& params) {
  return backend::prefilter({m.relative, m.proj_err_rms_px, m.num_points, m.slope}, params);
}

}  // namespace vslam::frontend
