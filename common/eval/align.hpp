#pragma once
// Alignment of an estimated trajectory to the reference before the absolute
// trajectory error, by Umeyama's closed form (least squares over the
// associated positions: minimise sum_i |ref_i - (s R est_i + t)|^2):
//   none  identity;
//   se2   rotation about z and translation in x, y (z untouched): the planar
//         robot's frames differ by a floor-plane motion only;
//   se3   rotation and translation (evaluate_ate.py, evo -a);
//   sim3  rotation, translation and scale (evo -as; monocular estimates).
//   origin  the rigid motion that puts the estimate's first associated pose
//         on the reference's (evo --align_origin): a dead-reckoned path
//         started where the robot really started, as in the vSLAM paper's
//         Figs. 7 and 9; not a least-squares fit.

#include <Eigen/Geometry>
#include <optional>
#include <string>
#include <vector>

#include "eval/trajectory.hpp"

namespace vslam::eval {

enum class AlignMode { kNone, kSE2, kSE3, kSim3, kOrigin };

std::optional<AlignMode> parseAlignMode(const std::string& word);
std::string toString(AlignMode mode);

// x -> scale * R * x + t, mapping the estimate's frame into the reference's.
struct Similarity {
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
  double scale = 1.0;

  Eigen::Vector3d apply(const Eigen::Vector3d& p) const { return scale * (R * p) + t; }
  StampedPose apply(const StampedPose& p) const;
  Trajectory apply(const Trajectory& traj) const;
  double rotationAngle() const;  // radians, of R
  double yaw() const;            // radians, heading change of R's x axis about z
};

// ref_first * est_first^-1: maps the estimate's first pose onto the reference's.
Similarity alignOrigin(const StampedPose& est_first, const StampedPose& ref_first);

// Minimum number of associated poses each mode needs.
std::size_t minPairsFor(AlignMode mode);

// The transform of family `mode` that best maps `est` onto `ref` (same size,
// element i of each associated). Throws DataError if there are fewer than
// minPairsFor(mode) points, or for sim3 if the estimate does not move.
Similarity alignPositions(const std::vector<Eigen::Vector3d>& est,
                          const std::vector<Eigen::Vector3d>& ref, AlignMode mode);

}  // namespace vslam::eval
