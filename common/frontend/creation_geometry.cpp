#include "frontend/creation_geometry.hpp"

#include <ceres/ceres.h>
#include <ceres/rotation.h>

#include <Eigen/Eigenvalues>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/calib3d.hpp>

#include "util/statistics.hpp"

namespace vslam::frontend {

Eigen::Vector3d angleAxisFromRotation(const Eigen::Matrix3d& rotation) {
  const Eigen::AngleAxisd aa(rotation);
  return aa.angle() * aa.axis();
}

Eigen::Matrix3d rotationFromAngleAxis(const Eigen::Vector3d& angle_axis) {
  const double angle = angle_axis.norm();
  if (angle < 1e-15) return Eigen::Matrix3d::Identity();
  return Eigen::AngleAxisd(angle, angle_axis / angle).toRotationMatrix();
}

bool triangulateDlt(const Eigen::Isometry3d* cam_T_ref, const Eigen::Vector2d* x, int n,
                    Eigen::Vector3d* point_ref) {
  // Each view gives two rows of A X = 0 for the homogeneous point X:
  // x P3 - P1 and y P3 - P2 with P = [R | t].
  Eigen::Matrix4d ata = Eigen::Matrix4d::Zero();
  for (int k = 0; k < n; ++k) {
    const Eigen::Matrix<double, 3, 4> p = cam_T_ref[k].matrix().topRows<3>();
    const Eigen::Matrix<double, 1, 4> r0 = x[k].x() * p.row(2) - p.row(0);
    const Eigen::Matrix<double, 1, 4> r1 = x[k].y() * p.row(2) - p.row(1);
    ata.noalias() += r0.transpose() * r0 + r1.transpose() * r1;
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix4d> eig(ata);
  const Eigen::Vector4d h = eig.eigenvectors().col(0);  // smallest eigenvalue
  if (!h.allFinite() || std::abs(h[3]) < 1e-12 * h.head<3>().norm()) return false;
  *point_ref = h.head<3>() / h[3];
  return point_ref->allFinite();
}

namespace {

// Least-squares rotation R with b2 ~ R b1 over the selected ray pairs.
Eigen::Matrix3d fitRotation(const std::vector<Eigen::Vector3d>& b1,
                            const std::vector<Eigen::Vector3d>& b2,
                            const std::vector<uint8_t>& use) {
  Eigen::Matrix3d h = Eigen::Matrix3d::Zero();
  for (size_t i = 0; i < b1.size(); ++i)
    if (use[i]) h.noalias() += b1[i] * b2[i].transpose();
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(h, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d d = Eigen::Matrix3d::Identity();
  d(2, 2) = (svd.matrixV() * svd.matrixU().transpose()).determinant() < 0 ? -1.0 : 1.0;
  return svd.matrixV() * d * svd.matrixU().transpose();
}

}  // namespace

double medianRotationOnlyResidual(const std::vector<Eigen::Vector2d>& x1,
                                  const std::vector<Eigen::Vector2d>& x2) {
  const size_t n = std::min(x1.size(), x2.size());
  if (n < 3) return std::numeric_limits<double>::quiet_NaN();
  std::vector<Eigen::Vector3d> b1(n), b2(n);
  for (size_t i = 0; i < n; ++i) {
    b1[i] = x1[i].homogeneous().normalized();
    b2[i] = x2[i].homogeneous().normalized();
  }
  std::vector<uint8_t> use(n, 1);
  std::vector<double> residual(n);
  double med = 0.0;
  for (int round = 0; round < 2; ++round) {
    const Eigen::Matrix3d r = fitRotation(b1, b2, use);
    for (size_t i = 0; i < n; ++i) {
      const Eigen::Vector3d rb = r * b1[i];
      residual[i] = std::atan2(rb.cross(b2[i]).norm(), rb.dot(b2[i]));
    }
    std::vector<double> sorted = residual;
    med = upperMedian(&sorted);
    for (size_t i = 0; i < n; ++i) use[i] = residual[i] <= 3.0 * med;
  }
  return med;
}

double sampsonDistance(const Eigen::Isometry3d& cam2_T_cam1, const Eigen::Vector2d& x1,
                       const Eigen::Vector2d& x2) {
  const Eigen::Vector3d t = cam2_T_cam1.translation();
  const Eigen::Matrix3d& r = cam2_T_cam1.linear();
  const Eigen::Vector3d h1 = x1.homogeneous(), h2 = x2.homogeneous();
  const Eigen::Vector3d l2 = t.cross(r * h1);              // E x1
  const Eigen::Vector3d l1 = r.transpose() * h2.cross(t);  // E^T x2
  const double denom = std::sqrt(l2.head<2>().squaredNorm() + l1.head<2>().squaredNorm());
  return denom > 0 ? h2.dot(l2) / denom : std::numeric_limits<double>::infinity();
}

namespace {

// Sampson approximation of the geometric epipolar error of x2^T E x1,
// E = [t]x R (X2 = R X1 + t): with l2 = E x1 = t x (R x1) and
// l1 = E^T x2 = R^T (x2 x t), d = x2.l2 / sqrt(l2x^2 + l2y^2 + l1x^2 + l1y^2).
// Parameters: angle-axis of R (3), t on the unit sphere (3, 2 DOF).
struct SampsonCost {
  SampsonCost(const Eigen::Vector2d& a, const Eigen::Vector2d& b) : x1(a), x2(b) {}

  template <typename T>
  bool operator()(const T* angle_axis, const T* t, T* residual) const {
    const T h1[3] = {T(x1.x()), T(x1.y()), T(1.0)};
    const T h2[3] = {T(x2.x()), T(x2.y()), T(1.0)};
    T rh1[3];
    ceres::AngleAxisRotatePoint(angle_axis, h1, rh1);
    T l2[3];
    ceres::CrossProduct(t, rh1, l2);
    T c[3];
    ceres::CrossProduct(h2, t, c);
    const T inverse[3] = {-angle_axis[0], -angle_axis[1], -angle_axis[2]};
    T l1[3];
    ceres::AngleAxisRotatePoint(inverse, c, l1);
    const T e = ceres::DotProduct(h2, l2);
    const T denom2 = l2[0] * l2[0] + l2[1] * l2[1] + l1[0] * l1[0] + l1[1] * l1[1];
    residual[0] = e / sqrt(denom2 + T(1e-300));
    return true;
  }

  static ceres::CostFunction* Create(const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
    return new ceres::AutoDiffCostFunction<SampsonCost, 1, 3, 3>(new SampsonCost(a, b));
  }

  Eigen::Vector2d x1, x2;
};

}  // namespace

bool estimateTwoView(const std::vector<Eigen::Vector2d>& x1, const std::vector<Eigen::Vector2d>& x2,
                     const TwoViewParams& params, TwoViewResult* result) {
  const size_t n = x1.size();
  result->inliers.assign(n, 0);
  result->ransac_inliers = result->num_inliers = 0;
  if (n < 5 || x2.size() != n) return false;
  std::vector<cv::Point2d> p1(n), p2(n);
  for (size_t i = 0; i < n; ++i) {
    p1[i] = {x1[i].x(), x1[i].y()};
    p2[i] = {x2[i].x(), x2[i].y()};
  }
  cv::Mat mask;
  const cv::Mat eye = cv::Mat::eye(3, 3, CV_64F);
  const cv::Mat e_all = cv::findEssentialMat(p1, p2, eye, cv::RANSAC, params.confidence,
                                             params.threshold, params.max_iterations, mask);
  if (e_all.rows < 3 || e_all.cols != 3) return false;
  const cv::Mat e = e_all.rowRange(0, 3);
  cv::Mat r_cv, t_cv;
  result->ransac_inliers = cv::recoverPose(e, p1, p2, eye, r_cv, t_cv, mask);
  if (result->ransac_inliers < 5) return false;

  Eigen::Matrix3d r;
  Eigen::Vector3d t;
  for (int a = 0; a < 3; ++a) {
    t[a] = t_cv.at<double>(a);
    for (int b = 0; b < 3; ++b) r(a, b) = r_cv.at<double>(a, b);
  }
  for (size_t i = 0; i < n; ++i) result->inliers[i] = mask.at<uint8_t>(static_cast<int>(i)) != 0;

  Eigen::Vector3d angle_axis = angleAxisFromRotation(r);
  t.normalize();
  for (int round = 0; round < params.refine_rounds; ++round) {
    if (std::count(result->inliers.begin(), result->inliers.end(), 1) < 5) return false;
    ceres::Problem problem;
    ceres::LossFunction* loss = new ceres::HuberLoss(params.threshold);  // shared, owned once
    for (size_t i = 0; i < n; ++i) {
      if (result->inliers[i])
        problem.AddResidualBlock(SampsonCost::Create(x1[i], x2[i]), loss, angle_axis.data(),
                                 t.data());
    }
    problem.SetManifold(t.data(), new ceres::SphereManifold<3>());
    ceres::Solver::Options options;
    options.linear_solver_type = ceres::DENSE_QR;  // 5 parameters
    options.max_num_iterations = 10;
    options.num_threads = 1;
    options.logging_type = ceres::SILENT;
    ceres::Solver::Summary summary;
    ceres::Solve(options, &problem, &summary);
    if (!angle_axis.allFinite() || !t.allFinite()) return false;
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
    pose.linear() = rotationFromAngleAxis(angle_axis);
    pose.translation() = t.normalized();
    // Inliers among all correspondences: small epipolar error and in front
    // of both cameras.
    for (size_t i = 0; i < n; ++i) {
      bool in = std::abs(sampsonDistance(pose, x1[i], x2[i])) < params.threshold;
      if (in) {
        const Eigen::Isometry3d cams[2] = {Eigen::Isometry3d::Identity(), pose};
        const Eigen::Vector2d xs[2] = {x1[i], x2[i]};
        Eigen::Vector3d p;
        in = triangulateDlt(cams, xs, 2, &p) && p.z() > 0 && (pose * p).z() > 0;
      }
      result->inliers[i] = in;
    }
    result->cam2_T_cam1 = pose;
  }
  if (params.refine_rounds <= 0) {
    result->cam2_T_cam1.linear() = r;
    result->cam2_T_cam1.translation() = t;
  }
  result->num_inliers =
      static_cast<int>(std::count(result->inliers.begin(), result->inliers.end(), 1));
  return result->num_inliers >= 5;
}

double rangeSigma(const Eigen::Vector3d& point_ref, const Eigen::Isometry3d* cam_T_ref, int n,
                  double focal_px, double sigma_px) {
  Eigen::Matrix3d jtj = Eigen::Matrix3d::Zero();
  for (int k = 0; k < n; ++k) {
    const Eigen::Vector3d q = cam_T_ref[k] * point_ref;
    if (!(q.z() > 0)) return std::numeric_limits<double>::infinity();
    Eigen::Matrix<double, 2, 3> dproj;
    dproj << 1.0 / q.z(), 0.0, -q.x() / (q.z() * q.z()), 0.0, 1.0 / q.z(), -q.y() / (q.z() * q.z());
    const Eigen::Matrix<double, 2, 3> j = focal_px * dproj * cam_T_ref[k].linear();
    jtj.noalias() += j.transpose() * j;
  }
  const Eigen::Vector3d u = point_ref.normalized();
  const Eigen::LDLT<Eigen::Matrix3d> ldlt(jtj);
  if (ldlt.info() != Eigen::Success || !(ldlt.vectorD().minCoeff() > 1e-12 * jtj.trace()))
    return std::numeric_limits<double>::infinity();
  const double var = sigma_px * sigma_px * u.dot(ldlt.solve(u));
  return var > 0 && std::isfinite(var) ? std::sqrt(var) : std::numeric_limits<double>::infinity();
}

}  // namespace vslam::frontend
