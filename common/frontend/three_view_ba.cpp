#include "frontend/three_view_ba.hpp"

#include <ceres/ceres.h>
#include <ceres/rotation.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "frontend/creation_geometry.hpp"
#include "frontend/reprojection_cost.hpp"
#include "util/statistics.hpp"

namespace vslam::frontend {

namespace {

const Eigen::Vector2d& observation(const ThreeViewObservations& obs, size_t i, int view) {
  return view == 0 ? obs.x1[i] : view == 1 ? obs.x2[i] : obs.x3[i];
}

Eigen::Vector3d inView(const ThreeViewModel& model, size_t i, int view) {
  const Eigen::Vector3d& p = model.points[i];
  return view == 0 ? p : view == 1 ? model.cam2_T_cam1 * p : model.cam3_T_cam1 * p;
}

}  // namespace

double reprojectionErrorPx(const ThreeViewObservations& obs, const ThreeViewModel& model,
                           double focal_px, size_t i, int view) {
  const Eigen::Vector3d q = inView(model, i, view);
  if (!(q.z() > 0)) return std::numeric_limits<double>::infinity();
  return focal_px * (q.head<2>() / q.z() - observation(obs, i, view)).norm();
}

double reprojectionRmsPx(const ThreeViewObservations& obs, const ThreeViewModel& model,
                         double focal_px, const std::vector<uint8_t>& active) {
  double sum = 0.0;
  int count = 0;
  for (size_t i = 0; i < obs.size(); ++i) {
    if (!active[i]) continue;
    for (int view = 0; view < 3; ++view) {
      const double e = reprojectionErrorPx(obs, model, focal_px, i, view);
      sum += e * e;
      ++count;
    }
  }
  return count > 0 ? std::sqrt(sum / count) : 0.0;
}

ThreeViewBaReport threeViewBundleAdjust(const ThreeViewObservations& obs, double focal_px,
                                        const ThreeViewBaParams& params, ThreeViewModel* model,
                                        std::vector<uint8_t>* active) {
  ThreeViewBaReport report;
  const size_t n = obs.size();
  active->resize(n, 0);
  model->points.resize(n, Eigen::Vector3d(0, 0, 1));
  report.num_points_in = static_cast<int>(std::count(active->begin(), active->end(), 1));
  report.initial_rms_px = reprojectionRmsPx(obs, *model, focal_px, *active);

  // Parameter blocks. t2 lives on the unit sphere: the overall scale is the
  // gauge freedom the paper fixes with |t12| = 1.
  Eigen::Vector3d aa2 = angleAxisFromRotation(model->cam2_T_cam1.linear());
  Eigen::Vector3d t2 = model->cam2_T_cam1.translation().normalized();
  Eigen::Vector3d aa3 = angleAxisFromRotation(model->cam3_T_cam1.linear());
  Eigen::Vector3d t3 = model->cam3_T_cam1.translation() / model->cam2_T_cam1.translation().norm();
  std::vector<Eigen::Vector3d> points = model->points;
  for (auto& p : points) p /= model->cam2_T_cam1.translation().norm();
  auto writeBack = [&] {
    model->cam2_T_cam1.linear() = rotationFromAngleAxis(aa2);
    model->cam2_T_cam1.translation() = t2;
    model->cam3_T_cam1.linear() = rotationFromAngleAxis(aa3);
    model->cam3_T_cam1.translation() = t3;
    model->points = points;
  };
  if (!t2.allFinite() || !t3.allFinite()) {
    report.message = "initial view-2 translation is zero";
    return report;
  }

  ceres::Problem::Options problem_options;
  problem_options.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::HuberLoss loss(params.huber_px);
  ceres::Solver::Options options = smallProblemOptions(params.max_iterations);
  options.function_tolerance = params.function_tolerance;

  std::vector<double> components;
  for (int round = 0; round < params.max_rounds; ++round) {
    const int num_active = static_cast<int>(std::count(active->begin(), active->end(), 1));
    if (num_active < 6) {
      report.message = "fewer than 6 points left";
      return report;
    }
    ceres::Problem problem(problem_options);
    for (size_t i = 0; i < n; ++i) {
      if (!(*active)[i]) continue;
      double* p = points[i].data();
      problem.AddResidualBlock(ReferenceReprojectionCost::Create(obs.x1[i], focal_px), &loss, p);
      problem.AddResidualBlock(ReprojectionCost::Create(obs.x2[i], focal_px), &loss, aa2.data(),
                               t2.data(), p);
      problem.AddResidualBlock(ReprojectionCost::Create(obs.x3[i], focal_px), &loss, aa3.data(),
                               t3.data(), p);
    }
    problem.SetManifold(t2.data(), new ceres::SphereManifold<3>());
    ceres::Solver::Summary summary;
    ceres::Solve(options, &problem, &summary);
    ++report.rounds;
    report.iterations += static_cast<int>(summary.iterations.size()) - 1;
    if (!summary.IsSolutionUsable() || !aa2.allFinite() || !t2.allFinite() || !aa3.allFinite() ||
        !t3.allFinite()) {
      report.message = "solver failed: " + summary.message;
      return report;
    }
    writeBack();

    // Robust std of all residual components of the active points.
    components.clear();
    for (size_t i = 0; i < n; ++i) {
      if (!(*active)[i]) continue;
      for (int view = 0; view < 3; ++view) {
        const Eigen::Vector3d q = inView(*model, i, view);
        if (!(q.z() > 0)) continue;
        const Eigen::Vector2d r = focal_px * (q.head<2>() / q.z() - observation(obs, i, view));
        components.push_back(r.x());
        components.push_back(r.y());
      }
    }
    if (components.empty()) components.push_back(0.0);  // no residual: the floor below
    const double med = upperMedian(&components);
    for (double& c : components) c = std::abs(c - med);
    report.robust_sigma_px = std::max(params.min_sigma_px, 1.4826 * upperMedian(&components));
    const double limit = params.outlier_sigmas * report.robust_sigma_px;

    int dropped = 0;
    for (size_t i = 0; i < n; ++i) {
      if (!(*active)[i]) continue;
      for (int view = 0; view < 3; ++view) {
        if (!(reprojectionErrorPx(obs, *model, focal_px, i, view) <= limit)) {
          (*active)[i] = 0;
          ++dropped;
          break;
        }
      }
    }
    report.num_rejected += dropped;
    if (dropped == 0) break;
  }
  report.final_rms_px = reprojectionRmsPx(obs, *model, focal_px, *active);
  report.converged = std::isfinite(report.final_rms_px);
  if (!report.converged) report.message = "non-finite reprojection error";
  return report;
}

}  // namespace vslam::frontend
