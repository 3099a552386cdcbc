#pragma once
// Planar rigid transforms, the robot's pose convention throughout the stack:
// (x, y) metres, theta radians counter-clockwise, wrapped to (-pi, pi].
// Naming follows "a_T_b": pose of frame b expressed in frame a.

#include <Eigen/Core>
#include <cmath>

#include "util/angles.hpp"

namespace vslam {

struct Pose2 {
  double x = 0;
  double y = 0;
  double theta = 0;

  // a_T_c = a_T_b.compose(b_T_c)
  Pose2 compose(const Pose2& b) const {
    const double c = std::cos(theta), s = std::sin(theta);
    return {x + c * b.x - s * b.y, y + s * b.x + c * b.y, wrapAngle(theta + b.theta)};
  }
  Pose2 inverse() const {
    const double c = std::cos(theta), s = std::sin(theta);
    return {-c * x - s * y, s * x - c * y, wrapAngle(-theta)};
  }
  // this^-1 * other: `other` expressed in this pose's frame (one sine and
  // cosine, not inverse().compose()'s two: the particle filter's inner loop).
  Pose2 between(const Pose2& other) const {
    const double c = std::cos(theta), s = std::sin(theta);
    const double dx = other.x - x, dy = other.y - y;
    return {c * dx + s * dy, -s * dx + c * dy, wrapAngle(other.theta - theta)};
  }
  bool isFinite() const { return std::isfinite(x) && std::isfinite(y) && std::isfinite(theta); }
  Eigen::Vector3d vector() const { return {x, y, theta}; }
};

// The pose a fraction s (0..1) of the way from a to b. Two ways, as the
// samples are meant:
// - between poses of a trajectory sampled in time (ground truth, a rendered
//   path): x, y and theta each linearly, theta the short way round;
inline Pose2 interpolate(const Pose2& a, const Pose2& b, double s) {
  return {a.x + s * (b.x - a.x), a.y + s * (b.y - a.y),
          wrapAngle(a.theta + s * wrapAngle(b.theta - a.theta))};
}
// - between two odometry readings: that fraction of the motion from a to
//   b, in a's frame (the robot drove it).
inline Pose2 interpolateMotion(const Pose2& a, const Pose2& b, double s) {
  const Pose2 d = a.between(b);
  return a.compose({s * d.x, s * d.y, s * d.theta});
}

// A cumulative odometry pose with the path driven and the angle turned up
// to it: the odometry's drift between two of them grows with both (the
// pose graph's odometry edges, odometryAgrees).
struct OdometryAt {
  Pose2 pose;
  double distance_m = 0;
  double rotation_rad = 0;
};
// Between two of them: interpolateMotion, and the totals linearly.
inline OdometryAt interpolateOdometry(const OdometryAt& a, const OdometryAt& b, double s) {
  return {interpolateMotion(a.pose, b.pose, s), a.distance_m + s * (b.distance_m - a.distance_m),
          a.rotation_rad + s * (b.rotation_rad - a.rotation_rad)};
}

}  // namespace vslam
