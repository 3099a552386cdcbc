#include "odometry/odometry_gate.hpp"

#include <algorithm>
#include <cmath>

#include "util/angles.hpp"

namespace vslam {

bool odometryAgrees(const Pose2& measured, const Pose2& by_odometry, double path_m, double turn_rad,
                    const OdometryGate& gate) {
  if (gate.sigmas <= 0) return true;
  const double path = std::max(path_m, 0.0);
  const double sigma_heading = gate.sigma_rotation * std::sqrt(path + std::max(turn_rad, 0.0));
  const double sigma_position = gate.sigma_translation * std::sqrt(path) + sigma_heading * path / 2;
  const double error_m = std::hypot(measured.x - by_odometry.x, measured.y - by_odometry.y);
  const double error_rad = std::abs(wrapAngle(measured.theta - by_odometry.theta));
  const double measurement_m =
      gate.min_error_m + gate.error_per_m * std::hypot(measured.x, measured.y);
  return error_m <= gate.sigmas * sigma_position + measurement_m &&
         error_rad <= gate.sigmas * sigma_heading + gate.min_error_rad;
}

bool odometryAgrees(const Pose2& measured, const OdometryAt& created, const OdometryAt& now,
                    const OdometryGate& gate) {
  return odometryAgrees(measured, created.pose.between(now.pose),
                        now.distance_m - created.distance_m,
                        now.rotation_rad - created.rotation_rad, gate);
}

}  // namespace vslam
