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
  // this^-1 * other: `other` expressed in this pose's frame.
  Pose2 between(const Pose2& other) const { return inverse().compose(other); }
  bool isFinite() const { return std::isfinite(x) && std::isfinite(y) && std::isfinite(theta); }
  Eigen::Vector3d vector() const { return {x, y, theta}; }
};

}  // namespace vslam
