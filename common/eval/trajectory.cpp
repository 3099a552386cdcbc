#include "eval/trajectory.hpp"

#include <algorithm>
#include <cmath>

namespace vslam::eval {

Eigen::Isometry3d StampedPose::isometry() const {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = orientation.normalized().toRotationMatrix();
  T.translation() = position;
  return T;
}

StampedPose planarPose(double t, double x, double y, double z, double theta) {
  StampedPose p;
  p.t = t;
  p.position = {x, y, z};
  p.orientation = Eigen::Quaterniond(Eigen::AngleAxisd(theta, Eigen::Vector3d::UnitZ()));
  return p;
}

double headingOf(const Eigen::Quaterniond& q) {
  const Eigen::Vector3d x_axis = q.normalized() * Eigen::Vector3d::UnitX();
  return std::atan2(x_axis.y(), x_axis.x());
}

std::vector<double> Trajectory::stamps() const {
  std::vector<double> out;
  out.reserve(poses.size());
  for (const auto& p : poses) out.push_back(p.t);
  return out;
}

double Trajectory::pathLength() const {
  double sum = 0;
  for (std::size_t i = 1; i < poses.size(); ++i) {
    sum += (poses[i].position - poses[i - 1].position).norm();
  }
  return sum;
}

std::size_t sortByTime(Trajectory* traj) {
  auto& v = traj->poses;
  std::stable_sort(v.begin(), v.end(),
                   [](const StampedPose& a, const StampedPose& b) { return a.t < b.t; });
  std::vector<StampedPose> out;
  out.reserve(v.size());
  for (const auto& p : v) {
    if (!out.empty() && out.back().t == p.t) {
      out.back() = p;  // the later one wins
    } else {
      out.push_back(p);
    }
  }
  const std::size_t dropped = v.size() - out.size();
  v = std::move(out);
  return dropped;
}

}  // namespace vslam::eval
