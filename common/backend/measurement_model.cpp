#include "backend/measurement_model.hpp"

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <cmath>

namespace vslam::backend {

Eigen::Matrix3d measurementJacobianLandmark(const Pose2& s, const Pose2& phi) {
  const Pose2 y = predictMeasurement(s, phi);
  const double c = std::cos(phi.theta), sn = std::sin(phi.theta);
  Eigen::Matrix3d h;
  h << -c, -sn, y.y,  //
      sn, -c, -y.x,   //
      0, 0, -1;
  return h;
}

LandmarkEstimate initializeLandmark(const Pose2& s, const Pose2& y, const Eigen::Matrix3d& r) {
  // phi_t = s_t - y_t;  phi_xy = s_xy - R(phi_t) y_xy  (from s = phi (+) y).
  const Pose2 phi = s.compose(y.inverse());
  const double c = std::cos(phi.theta), sn = std::sin(phi.theta);
  Eigen::Matrix3d j;                 // dphi / dy
  j << -c, sn, -sn * y.x - c * y.y,  //
      -sn, -c, c * y.x - sn * y.y,   //
      0, 0, -1;
  LandmarkEstimate lm;
  lm.mean = phi.vector();
  lm.covariance = j * r * j.transpose();
  lm.num_observations = 1;
  return lm;
}

Innovation innovation(const LandmarkEstimate& lm, const Pose2& s, const Pose2& y,
                      const Eigen::Matrix3d& r) {
  // predictMeasurement(s, phi) with one sine and cosine (this is the
  // filter's inner loop: twice per particle and measurement).
  const Pose2 phi = toPose(lm.mean);
  const double c = std::cos(phi.theta), sn = std::sin(phi.theta);
  const double dx = s.x - phi.x, dy = s.y - phi.y;
  const Pose2 predicted{c * dx + sn * dy, -sn * dx + c * dy, wrapAngle(s.theta - phi.theta)};
  Innovation in;
  in.nu = {y.x - predicted.x, y.y - predicted.y, wrapAngle(y.theta - predicted.theta)};
  in.h << -c, -sn, predicted.y,  //
      sn, -c, -predicted.x,      //
      0, 0, -1;
  in.s = in.h * lm.covariance * in.h.transpose() + r;
  const double det = in.s.determinant();
  in.s_inv = in.s.inverse();
  in.mahalanobis_sq = in.nu.dot(in.s_inv * in.nu);
  in.log_likelihood = logGaussian3(in.mahalanobis_sq, std::log(det));
  return in;
}

void kalmanUpdate(LandmarkEstimate& lm, const Innovation& in, const Eigen::Matrix3d& r) {
  const Eigen::Matrix3d k = lm.covariance * in.h.transpose() * in.s_inv;
  lm.mean += k * in.nu;
  lm.mean.z() = wrapAngle(lm.mean.z());
  const Eigen::Matrix3d a = Eigen::Matrix3d::Identity() - k * in.h;
  const Eigen::Matrix3d p = a * lm.covariance * a.transpose() + k * r * k.transpose();
  lm.covariance = 0.5 * (p + p.transpose());
  ++lm.num_observations;
}

Pose2 sampleFromMeasurement(const LandmarkEstimate& lm, const Pose2& y,
                            const Eigen::Matrix3d& chol_r, RandomStream& rng) {
  const Eigen::Matrix3d chol_p = lm.covariance.llt().matrixL();
  const Eigen::Vector3d n1(rng.normal(), rng.normal(), rng.normal());
  const Eigen::Vector3d n2(rng.normal(), rng.normal(), rng.normal());
  const Eigen::Vector3d phi = lm.mean + chol_p * n1;
  const Eigen::Vector3d rel = y.vector() + chol_r * n2;
  return toPose(phi).compose(toPose(rel));
}

}  // namespace vslam::backend
