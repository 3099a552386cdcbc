#pragma once
// A stamped 3-D trajectory, the common currency of the evaluation: ground
// truth, estimates and odometry from logs or TUM files all become one.
// Positions in metres, time in seconds (TUM's convention; log utimes are
// divided by 1e6), orientation as a unit quaternion world<-body.

#include <Eigen/Geometry>
#include <cstddef>
#include <string>
#include <vector>

namespace vslam::eval {

struct StampedPose {
  double t = 0;  // seconds
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();

  Eigen::Isometry3d isometry() const;
};

// A planar pose (x, y, heading theta about +z) at height z.
StampedPose planarPose(double t, double x, double y, double z, double theta);

// Heading of a pose: the angle of its body x axis projected onto the world
// x-y plane, counter-clockwise from +x (yaw for a planar pose).
double headingOf(const Eigen::Quaterniond& q);

struct Trajectory {
  std::string name;  // channel or file it came from
  std::vector<StampedPose> poses;

  bool empty() const { return poses.empty(); }
  std::size_t size() const { return poses.size(); }
  std::vector<double> stamps() const;
  double duration() const { return empty() ? 0.0 : poses.back().t - poses.front().t; }
  double pathLength() const;
};

// Sorts by time; of several poses with the same timestamp keeps the last one
// read (as a TUM script's dictionary does). Returns how many were dropped.
std::size_t sortByTime(Trajectory* traj);

}  // namespace vslam::eval
