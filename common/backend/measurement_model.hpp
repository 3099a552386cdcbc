#pragma once
// The measurement model of the vSLAM back-end (paper section 6, eq. 2) and
// the Kalman filter of one landmark.
//
// A landmark's pose phi is the robot pose (map frame) when the landmark was
// created. A visual measurement y is the robot's current pose s expressed in
// the frame of phi:
//
//   y = h(s, phi) + v = phi^-1 (+) s + v,      v ~ N(0, R),  R = Sigma_vis
//
//   h_x     =  cos(phi_t) (s_x - phi_x) + sin(phi_t) (s_y - phi_y)
//   h_y     = -sin(phi_t) (s_x - phi_x) + cos(phi_t) (s_y - phi_y)
//   h_theta =  s_t - phi_t                                  (wrapped)
//
// Jacobian with respect to the landmark (the Kalman filter's state):
//
//   H = dh/dphi = [ -cos(phi_t)  -sin(phi_t)   h_y ]
//                 [  sin(phi_t)  -cos(phi_t)  -h_x ]
//                 [  0            0           -1   ]
//
// and with respect to the robot pose, dh/ds = [R(phi_t)^T 0; 0 1]: a rotation,
// |det dh/ds| = 1. That last fact is what makes the importance factors of the
// mixture proposal simple (docs/backend.md, "Mixture proposal").

#include <Eigen/Core>

#include "backend/landmark_map.hpp"
#include "backend/rng.hpp"
#include "odometry/pose2.hpp"

namespace vslam::backend {

inline Pose2 toPose(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }

// h(s, phi): the measurement a robot at s makes of a landmark at phi.
inline Pose2 predictMeasurement(const Pose2& s, const Pose2& phi) { return phi.between(s); }

// dh/dphi at (s, phi).
Eigen::Matrix3d measurementJacobianLandmark(const Pose2& s, const Pose2& phi);

// Landmark initialisation on its first measurement: phi = s (+) y^-1, with
// covariance J R J^T, J = dphi/dy. (Given the particle's path, the robot pose
// is exact; only the measurement is uncertain.)
LandmarkEstimate initializeLandmark(const Pose2& s, const Pose2& y, const Eigen::Matrix3d& r);

// What one landmark's measurement says about one particle.
struct Innovation {
  Eigen::Vector3d nu;  // y - h(s, phi), theta wrapped
  Eigen::Matrix3d h;   // dh/dphi
  Eigen::Matrix3d s;   // innovation covariance H P H^T + R
  Eigen::Matrix3d s_inv;
  double mahalanobis_sq;  // nu^T S^-1 nu
  double log_likelihood;  // log N(nu; 0, S), the marginal likelihood p(y | s, particle's map)
};
Innovation innovation(const LandmarkEstimate& lm, const Pose2& s, const Pose2& y,
                      const Eigen::Matrix3d& r);

// The Kalman update of the landmark given the robot pose s (Joseph form).
void kalmanUpdate(LandmarkEstimate& lm, const Innovation& in, const Eigen::Matrix3d& r);

// A robot pose drawn from the measurement model given the landmark: the
// landmark from its estimate and the true relative pose around y, then
// s = phi' (+) y'. Its density in s is the marginal likelihood p(y | s, map)
// normalised over s (the normaliser is 1 because |det dh/ds| = 1).
// chol_r: lower Cholesky factor of R.
Pose2 sampleFromMeasurement(const LandmarkEstimate& lm, const Pose2& y,
                            const Eigen::Matrix3d& chol_r, RandomStream& rng);

// log N(x; 0, cov) from the inverse and log-determinant of cov.
inline double logGaussian3(double mahalanobis_sq, double log_det_cov) {
  constexpr double kLog2Pi = 1.8378770664093453;
  return -0.5 * (mahalanobis_sq + log_det_cov + 3.0 * kLog2Pi);
}

}  // namespace vslam::backend
