#include "appearance/action_detector.hpp"

#include <cmath>

namespace vslam::appearance {

void ActionDetector::setReference(int64_t utime, const Pose2& odometry) {
  has_reference_ = true;
  completed_ = false;
  reference_utime_ = utime;
  reference_ = odometry;
  last_ = odometry;
  last_utime_ = utime;
  last_motion_utime_ = utime;
  travelled_ = 0;
  turned_ = 0;
}

std::optional<CompletedAction> ActionDetector::add(int64_t utime, const Pose2& odometry) {
  if (!has_reference_ || completed_ || utime <= last_utime_) return std::nullopt;
  const Pose2 step = last_.between(odometry);
  const double dt = 1e-6 * static_cast<double>(utime - last_utime_);
  const double d = std::hypot(step.x, step.y);
  const double a = std::abs(step.theta);
  travelled_ += d;
  turned_ += a;
  if (d > params_.rest_speed_mps * dt || a > params_.rest_turn_rate_rps * dt) {
    last_motion_utime_ = utime;
  }
  last_ = odometry;
  last_utime_ = utime;

  const bool full = travelled_ >= params_.distance_m || turned_ >= params_.turn_rad;
  const bool resting = 1e-6 * static_cast<double>(utime - last_motion_utime_) >= params_.rest_s;
  const bool enough = travelled_ >= params_.min_fraction * params_.distance_m ||
                      turned_ >= params_.min_fraction * params_.turn_rad;
  if (!full && !(resting && enough)) return std::nullopt;
  completed_ = true;
  CompletedAction out;
  out.utime = utime;
  out.delta = reference_.between(odometry);
  out.odometry = odometry;
  out.travelled_m = travelled_;
  out.turned_rad = turned_;
  return out;
}

}  // namespace vslam::appearance
