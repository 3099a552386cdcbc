#pragma once
// Wheel odometry of the simulated robot: the true motion of each step,
// scaled during scripted slip events, distorted by the wheels' scale and
// heading biases, plus noise drawn from the same model the
// estimators assume (MotionNoise: variances proportional to the step, so the
// error statistics do not depend on the odometry rate), accumulated into the
// cumulative dead-reckoned pose that vslam.odometry_t carries.

#include <random>

#include "odometry/motion_model.hpp"
#include "sim/scenario.hpp"

namespace vslam::sim {

class OdometrySimulator {
 public:
  OdometrySimulator(const OdometryParams& params, uint64_t seed);

  // Adds one step of true motion (robot frame) at sim time t (seconds).
  void addStep(const Pose2& true_step, double t);
  // Replaces the pose by an externally given odometry pose (trajectory mode).
  void setPose(const Pose2& pose);

  const Pose2& pose() const { return pose_; }
  double distance() const { return distance_; }
  double rotation() const { return rotation_; }
  const Pose2& lastStep() const { return last_step_; }

 private:
  OdometryParams params_;
  MotionNoise noise_;
  std::mt19937_64 rng_;
  std::normal_distribution<double> n01_;
  Pose2 pose_;
  Pose2 last_step_;
  double distance_ = 0;
  double rotation_ = 0;
};

}  // namespace vslam::sim
