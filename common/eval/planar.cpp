#include "eval/planar.hpp"

#include <cmath>

#include "util/angles.hpp"

namespace vslam::eval {

std::optional<FloorAxes> parseFloorAxes(const std::string& word) {
  if (word == "xy") return FloorAxes::kXY;
  if (word == "xz") return FloorAxes::kXZ;
  return std::nullopt;
}

std::string toString(FloorAxes axes) { return axes == FloorAxes::kXY ? "xy" : "xz"; }

PlanarPose planarFromPose(const Eigen::Isometry3d& world_T_body, FloorAxes axes) {
  const Eigen::Vector3d a = Eigen::Vector3d::UnitX();
  const Eigen::Vector3d b =
      axes == FloorAxes::kXY ? Eigen::Vector3d::UnitY() : Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d up = a.cross(b);
  const Eigen::Vector3d p = world_T_body.translation();
  const Eigen::Vector3d f = world_T_body.linear() * Eigen::Vector3d::UnitX();
  PlanarPose out;
  out.x = p.dot(a);
  out.y = p.dot(b);
  out.z = p.dot(up);
  out.theta = wrapAngle(std::atan2(f.dot(b), f.dot(a)));
  return out;
}

}  // namespace vslam::eval
