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
  // predictMeasurement(s, phi) with one sine and cosine, and S = H P H^T + R
  // and its inverse written out for H's zeros and S's symmetry: this is the
  // filter's inner loop (once or twice per particle and measurement).
  const Pose2 phi = toPose(lm.mean);
  const double c = std::cos(phi.theta), sn = std::sin(phi.theta);
  const double dx = s.x - phi.x, dy = s.y - phi.y;
  const double px = c * dx + sn * dy, py = -sn * dx + c * dy;
  Innovation in;
  in.nu = {y.x - px, y.y - py, wrapAngle(y.theta - wrapAngle(s.theta - phi.theta))};
  in.h << -c, -sn, py,  //
      sn, -c, -px,      //
      0, 0, -1;
  // a = P h0^T, b = P h1^T (h_i: the rows of H; P h2^T = -P's last column).
  const Eigen::Matrix3d& p = lm.covariance;
  const Eigen::Vector3d a = -c * p.col(0) - sn * p.col(1) + py * p.col(2);
  const Eigen::Vector3d b = sn * p.col(0) - c * p.col(1) - px * p.col(2);
  const double s00 = -c * a(0) - sn * a(1) + py * a(2) + r(0, 0);
  const double s01 = sn * a(0) - c * a(1) - px * a(2) + r(0, 1);
  const double s02 = -a(2) + r(0, 2);
  const double s11 = sn * b(0) - c * b(1) - px * b(2) + r(1, 1);
  const double s12 = -b(2) + r(1, 2);
  const double s22 = p(2, 2) + r(2, 2);
  in.s << s00, s01, s02,  //
      s01, s11, s12,      //
      s02, s12, s22;
  // The inverse from the cofactors of the symmetric S.
  const double c00 = s11 * s22 - s12 * s12, c01 = s02 * s12 - s01 * s22,
               c02 = s01 * s12 - s02 * s11, c11 = s00 * s22 - s02 * s02,
               c12 = s01 * s02 - s00 * s12, c22 = s00 * s11 - s01 * s01;
  const double det = s00 * c00 + s01 * c01 + s02 * c02;
  const double inv_det = 1.0 / det;
  in.s_inv << c00 * inv_det, c01 * inv_det, c02 * inv_det,  //
      c01 * inv_det, c11 * inv_det, c12 * inv_det,          //
      c02 * inv_det, c12 * inv_det, c22 * inv_det;
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
