#pragma once
// Planar robot poses from 3-D poses, for importing datasets whose ground
// truth is a 6-DoF pose (TUM RGB-D: the colour camera's optical centre in
// the motion-capture frame).
//
// The floor plane is spanned by two world axes (a, b); up is a x b:
//   xy  floor = world x, y; up = +z   (TUM RGB-D's motion-capture frame)
//   xz  floor = world x, z; up = -y   (a camera-like world frame, y down)
// The planar pose of a body is then
//   x = p.a, y = p.b, z = p.up, theta = atan2(f.b, f.a)
// with p its position and f its forward (x) axis in world coordinates.

#include <Eigen/Geometry>
#include <optional>
#include <string>

namespace vslam::eval {

enum class FloorAxes { kXY, kXZ };
std::optional<FloorAxes> parseFloorAxes(const std::string& word);
std::string toString(FloorAxes axes);

struct PlanarPose {
  double x = 0, y = 0;  // metres, in the floor plane
  double z = 0;         // metres, height along up
  double theta = 0;     // radians, (-pi, pi], counter-clockwise seen from above
};

PlanarPose planarFromPose(const Eigen::Isometry3d& world_T_body, FloorAxes axes);

}  // namespace vslam::eval
