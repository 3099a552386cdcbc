#include "odometry/motion_model.hpp"

#include <cmath>

namespace vslam {

Eigen::Matrix3d alongTrackCovariance(const Pose2& step, double var_translation,
                                     double var_rotation) {
  const double d = std::hypot(step.x, step.y);
  const double heading = d > 1e-9 ? std::atan2(step.y, step.x) : 0.0;
  const double c = std::cos(heading), s = std::sin(heading);
  Eigen::Matrix3d q = Eigen::Matrix3d::Zero();
  q(0, 0) = c * c * var_translation;
  q(0, 1) = q(1, 0) = c * s * var_translation;
  q(1, 1) = s * s * var_translation;
  q(2, 2) = var_rotation;
  return q;
}

Eigen::Matrix3d MotionNoise::stepCovariance(const Pose2& step) const {
  const double d = std::hypot(step.x, step.y);
  return alongTrackCovariance(step, sigma_translation * sigma_translation * d,
                              sigma_rotation * sigma_rotation * (d + std::abs(step.theta)));
}

MotionNoise::StepNoise::StepNoise(const MotionNoise& noise, const Pose2& step) : step_(step) {
  const double d = std::hypot(step.x, step.y);
  sigma_t_ = noise.sigma_translation * std::sqrt(d);
  sigma_r_ = noise.sigma_rotation * std::sqrt(d + std::abs(step.theta));
  const double heading = d > 1e-9 ? std::atan2(step.y, step.x) : 0.0;
  cos_heading_ = std::cos(heading);
  sin_heading_ = std::sin(heading);
}

Pose2 MotionNoise::perturb(const Pose2& step, double n_translation, double n_rotation) const {
  return StepNoise(*this, step).perturb(n_translation, n_rotation);
}

void PoseWithCovariance::apply(const Pose2& step, const Eigen::Matrix3d& step_covariance) {
  const double c = std::cos(pose_.theta), s = std::sin(pose_.theta);
  Eigen::Matrix3d f;
  f << 1, 0, -s * step.x - c * step.y,  //
      0, 1, c * step.x - s * step.y,    //
      0, 0, 1;
  Eigen::Matrix3d g;
  g << c, -s, 0,  //
      s, c, 0,    //
      0, 0, 1;
  covariance_ = f * covariance_ * f.transpose() + g * step_covariance * g.transpose();
  pose_ = pose_.compose(step);
}

OdometryIncrements::OdometryIncrements(double max_step_m, double max_step_rad)
    : max_step_m_(max_step_m), max_step_rad_(max_step_rad) {}

OdometryIncrements::Outcome OdometryIncrements::add(const OdometryReading& reading, Pose2* step) {
  if (!reading.pose.isFinite()) return Outcome::kInvalid;
  if (!last_) {
    last_ = reading;
    return Outcome::kFirst;
  }
  if (reading.seq <= last_->seq) {
    // A driver restart starts counting again from a small seq; anything else
    // at or below the last seq is a duplicate or arrived late.
    const bool restarted = reading.seq < last_->seq && reading.seq < 10 && last_->seq >= 10;
    if (!restarted) return Outcome::kStale;
    last_ = reading;
    return Outcome::kReset;
  }
  const Pose2 delta = last_->pose.between(reading.pose);
  if (std::hypot(delta.x, delta.y) > max_step_m_ || std::abs(delta.theta) > max_step_rad_) {
    last_ = reading;
    return Outcome::kImplausible;
  }
  last_ = reading;
  *step = delta;
  return Outcome::kStep;
}

const char* OdometryIncrements::describe(Outcome outcome) {
  switch (outcome) {
    case Outcome::kFirst:
      return "first reading";
    case Outcome::kStep:
      return "step";
    case Outcome::kStale:
      return "duplicate or out-of-order reading ignored";
    case Outcome::kInvalid:
      return "non-finite pose ignored";
    case Outcome::kReset:
      return "odometry driver restarted; reference reset";
    case Outcome::kImplausible:
      return "implausible jump; reference reset without motion";
  }
  return "?";
}

}  // namespace vslam
