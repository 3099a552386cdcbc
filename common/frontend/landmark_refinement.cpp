#include "frontend/landmark_refinement.hpp"

#include <ceres/ceres.h>
#include <ceres/rotation.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "frontend/creation_geometry.hpp"
#include "frontend/reprojection_cost.hpp"
#include "util/statistics.hpp"

namespace vslam::frontend {

namespace {

void require(bool condition, const char* field, const char* what) {
  if (!condition)
    throw std::invalid_argument(std::string("RefinementParams.") + field + " " + what);
}

// Prior on a view's robot position in the view-1 robot frame from odometry,
// in units of its std. The view's camera is X_k = R(aa) X + t (X in the
// view-1 camera frame); its robot's origin is robot_in_camera in the camera
// frame, so R^T (robot_in_camera - t) in the view-1 camera frame, and
// robot_T_camera maps that into the view-1 robot frame.
struct OdometryPositionCost {
  OdometryPositionCost(const Eigen::Isometry3d& robot_T_camera, const Eigen::Vector2d& odometry_xy,
                       double sigma_m)
      : rotation(robot_T_camera.linear()),
        translation(robot_T_camera.translation()),
        robot_in_camera(robot_T_camera.inverse().translation()),
        odometry(odometry_xy),
        sigma(sigma_m) {}

  template <typename T>
  bool operator()(const T* angle_axis, const T* t, T* residual) const {
    const T d[3] = {T(robot_in_camera.x()) - t[0], T(robot_in_camera.y()) - t[1],
                    T(robot_in_camera.z()) - t[2]};
    const T inverse_angle_axis[3] = {-angle_axis[0], -angle_axis[1], -angle_axis[2]};
    T p[3];
    ceres::AngleAxisRotatePoint(inverse_angle_axis, d, p);
    for (int row = 0; row < 2; ++row) {
      const T q = T(rotation(row, 0)) * p[0] + T(rotation(row, 1)) * p[1] +
                  T(rotation(row, 2)) * p[2] + T(translation(row));
      residual[row] = (q - T(odometry(row))) / T(sigma);
    }
    return true;
  }

  static ceres::CostFunction* Create(const Eigen::Isometry3d& robot_T_camera,
                                     const Eigen::Vector2d& odometry_xy, double sigma_m) {
    return new ceres::AutoDiffCostFunction<OdometryPositionCost, 2, 3, 3>(
        new OdometryPositionCost(robot_T_camera, odometry_xy, sigma_m));
  }

  Eigen::Matrix3d rotation;
  Eigen::Vector3d translation;
  Eigen::Vector3d robot_in_camera;
  Eigen::Vector2d odometry;
  double sigma;
};

// One observation of a landmark point in a view other than view 1.
struct Observation {
  int view = 0;  // index into the views below (0: creation view 2)
  int point = 0;
  Eigen::Vector2d normalized;
  bool later = false;  // from a later view (a candidate for rejection)
  bool active = true;
};

// A view after view 1: its camera as X_k = R(aa) X + t (X in the view-1
// camera frame) and its odometry relative to view 1.
struct ViewState {
  Eigen::Vector3d angle_axis;
  Eigen::Vector3d translation;
  Pose2 odometry;
};

Eigen::Vector3d inView(const ViewState& v, const Eigen::Vector3d& x) {
  return rotationFromAngleAxis(v.angle_axis) * x + v.translation;
}

void setCamera(ViewState* v, const Eigen::Isometry3d& cam_T_cam1) {
  v->angle_axis = angleAxisFromRotation(cam_T_cam1.linear());
  v->translation = cam_T_cam1.translation();
}

Eigen::Isometry3d cameraOf(const ViewState& v) {
  Eigen::Isometry3d cam_T_cam1 = Eigen::Isometry3d::Identity();
  cam_T_cam1.linear() = rotationFromAngleAxis(v.angle_axis);
  cam_T_cam1.translation() = v.translation;
  return cam_T_cam1;
}

}  // namespace

void RefinementParams::validate() const {
  require(huber_px > 0, "huber_px", "must be positive");
  require(max_iterations > 0, "max_iterations", "must be positive");
  require(max_rounds > 0, "max_rounds", "must be positive");
  require(outlier_sigmas > 0, "outlier_sigmas", "must be positive");
  require(min_sigma_px > 0, "min_sigma_px", "must be positive");
  require(odometry_sigma_per_sqrt_m >= 0, "odometry_sigma_per_sqrt_m", "must not be negative");
  require(odometry_sigma_floor_m > 0, "odometry_sigma_floor_m", "must be positive");
  require(min_span_m > 0, "min_span_m", "must be positive");
  require(min_observations >= 3, "min_observations", "must be at least 3");
  require(max_rms_px > 0, "max_rms_px", "must be positive");
}

RefinementReport refineLandmark(const std::array<Pose2, 3>& creation_odometry,
                                const std::vector<LaterView>& later, double focal_px,
                                const Eigen::Isometry3d& robot_T_camera,
                                const RefinementParams& params, CreatedLandmark* landmark) {
  RefinementReport report;
  const size_t n = landmark->points_robot.size();
  for (const auto& obs : landmark->observations) {
    if (obs.size() != n) {
      report.reason = "the landmark has no creation observations for its points";
      return report;
    }
  }
  const Eigen::Isometry3d camera_T_robot = robot_T_camera.inverse();

  // The views after view 1: the creation's two, then the later ones that
  // see enough points.
  std::vector<ViewState> views;
  std::vector<Observation> observations;
  for (int k = 1; k < 3; ++k) {
    ViewState v;
    setCamera(&v, (k == 1 ? landmark->robot1_T_camera2 : landmark->robot1_T_camera3).inverse() *
                      robot_T_camera);
    v.odometry = creation_odometry[0].between(creation_odometry[k]);
    views.push_back(v);
    for (size_t i = 0; i < n; ++i) {
      observations.push_back(
          {k - 1, static_cast<int>(i), landmark->observations[k][i], false, true});
    }
  }
  for (const LaterView& lv : later) {
    if (static_cast<int>(lv.points.size()) < params.min_observations ||
        lv.points.size() != lv.observations.size())
      continue;
    ViewState v;
    setCamera(&v, (lv.robot1_T_robot * robot_T_camera).inverse() * robot_T_camera);
    v.odometry = creation_odometry[0].between(lv.odometry);
    if (!v.angle_axis.allFinite() || !v.translation.allFinite()) continue;
    const int view = static_cast<int>(views.size());
    views.push_back(v);
    ++report.later_views;
    for (size_t j = 0; j < lv.points.size(); ++j) {
      if (lv.points[j] < 0 || static_cast<size_t>(lv.points[j]) >= n) continue;
      observations.push_back({view, lv.points[j], lv.observations[j], true, true});
      ++report.later_observations;
    }
    report.span_m = std::max(report.span_m, std::hypot(v.odometry.x, v.odometry.y));
  }
  if (report.later_views == 0) {
    report.reason = "no later view saw enough of its points";
    return report;
  }
  if (report.span_m < params.min_span_m) {
    report.reason = "the later views are too near the first";
    return report;
  }

  std::vector<Eigen::Vector3d> points(n);
  for (size_t i = 0; i < n; ++i) points[i] = camera_T_robot * landmark->points_robot[i];
  const std::vector<Eigen::Vector3d> initial_points = points;

  auto residualPx = [&](const Observation& o) -> double {
    const Eigen::Vector3d q = inView(views[o.view], points[o.point]);
    if (!(q.z() > 0)) return std::numeric_limits<double>::infinity();
    return focal_px * (q.head<2>() / q.z() - o.normalized).norm();
  };
  auto rmsPx = [&] {
    double sum = 0;
    int count = 0;
    for (size_t i = 0; i < n; ++i) {
      const Eigen::Vector2d r =
          focal_px * (points[i].head<2>() / points[i].z() - landmark->observations[0][i]);
      sum += r.squaredNorm();
      ++count;
    }
    for (const auto& o : observations) {
      if (!o.active) continue;
      const double e = residualPx(o);
      sum += e * e;
      ++count;
    }
    return count > 0 ? std::sqrt(sum / count) : 0.0;
  };
  report.rms_before_px = rmsPx();

  ceres::Problem::Options problem_options;
  problem_options.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::HuberLoss loss(params.huber_px);
  ceres::Solver::Options options = smallProblemOptions(params.max_iterations);

  std::vector<double> components;
  for (int round = 0; round < params.max_rounds; ++round) {
    ceres::Problem problem(problem_options);
    for (size_t i = 0; i < n; ++i) {
      problem.AddResidualBlock(
          ReferenceReprojectionCost::Create(landmark->observations[0][i], focal_px), &loss,
          points[i].data());
    }
    for (const auto& o : observations) {
      if (!o.active) continue;
      problem.AddResidualBlock(ReprojectionCost::Create(o.normalized, focal_px), &loss,
                               views[o.view].angle_axis.data(), views[o.view].translation.data(),
                               points[o.point].data());
    }
    // The odometry fixes the scale (the one freedom view 1 leaves) with
    // every view's distance, each weighed by how far the wheels went.
    for (auto& v : views) {
      const Eigen::Vector2d xy(v.odometry.x, v.odometry.y);
      const double sigma =
          params.odometry_sigma_floor_m + params.odometry_sigma_per_sqrt_m * std::sqrt(xy.norm());
      problem.AddResidualBlock(OdometryPositionCost::Create(robot_T_camera, xy, sigma), nullptr,
                               v.angle_axis.data(), v.translation.data());
    }
    ceres::Solver::Summary summary;
    ceres::Solve(options, &problem, &summary);
    bool finite = summary.IsSolutionUsable();
    for (const auto& v : views)
      finite = finite && v.angle_axis.allFinite() && v.translation.allFinite();
    for (const auto& p : points) finite = finite && p.allFinite() && p.z() > 0;
    if (!finite) {
      report.reason = "the solver failed: " + summary.message;
      return report;
    }

    // Robust std of every residual component; later views' observations
    // beyond outlier_sigmas of it are dropped (the creation's were vetted).
    components.clear();
    for (const auto& o : observations) {
      if (!o.active) continue;
      const Eigen::Vector3d q = inView(views[o.view], points[o.point]);
      if (!(q.z() > 0)) continue;
      const Eigen::Vector2d r = focal_px * (q.head<2>() / q.z() - o.normalized);
      components.push_back(r.x());
      components.push_back(r.y());
    }
    if (components.empty()) components.push_back(0.0);
    const double med = upperMedian(&components);
    for (double& c : components) c = std::abs(c - med);
    const double sigma = std::max(params.min_sigma_px, 1.4826 * upperMedian(&components));
    int dropped = 0;
    for (auto& o : observations) {
      if (!o.active || !o.later) continue;
      if (!(residualPx(o) <= params.outlier_sigmas * sigma)) {
        o.active = false;
        ++dropped;
      }
    }
    report.rejected_observations += dropped;
    if (dropped == 0) break;
  }
  for (const auto& o : observations) {
    if (o.active && !(residualPx(o) < std::numeric_limits<double>::infinity())) {
      report.reason = "a point ended up behind a camera";
      return report;
    }
  }
  report.rms_after_px = rmsPx();
  if (!(report.rms_after_px <= params.max_rms_px)) {
    report.reason = "reprojection RMS after the refinement above max_rms_px";
    return report;
  }

  std::vector<double> ratios, shifts;
  for (size_t i = 0; i < n; ++i) {
    ratios.push_back(points[i].norm() / initial_points[i].norm());
    shifts.push_back((points[i] - initial_points[i]).norm());
    landmark->points_robot[i] = robot_T_camera * points[i];
  }
  report.scale_change = median(ratios);
  report.median_point_shift_m = median(shifts);
  landmark->robot1_T_camera2 = robot_T_camera * cameraOf(views[0]).inverse();
  landmark->robot1_T_camera3 = robot_T_camera * cameraOf(views[1]).inverse();
  report.refined = true;
  return report;
}

}  // namespace vslam::frontend
