#pragma once
// Whether a landmark's measurement agrees with the odometry since the
// landmark was made: a wall pattern recognized one period along, or a door
// like the one it was made on, is measured where the odometry says the
// robot cannot be. The front-end uses it to decide whether a recognition
// covers its place (FrontendParams::coverage_gate).

#include "odometry/pose2.hpp"

namespace vslam {

// How far a measurement may disagree with the odometry since its landmark
// was made and still be of that landmark: `sigmas` times the odometry's
// drift over the path between (random walks of sigma_translation m/sqrt(m)
// and sigma_rotation rad/sqrt(m + rad), the heading's acting over half the
// path), plus the measurement's own error (min_error_m, growing by
// error_per_m per metre from the creation pose; min_error_rad). The sigmas
// are the worst of the wheel odometry this stack is meant for, not the
// typical: a true landmark must not be taken for a look-alike.
struct OdometryGate {
  double sigmas = 0;  // 0: off
  double sigma_translation = 0.05;
  double sigma_rotation = 0.04;
  double min_error_m = 0.10;
  double error_per_m = 0.10;
  double min_error_rad = 0.09;
};

// Whether `measured` (the robot in the landmark's creation frame) agrees
// with `by_odometry` (the same by the odometry), path_m driven and turn_rad
// turned in between, within `gate`. Always true when the gate is off.
bool odometryAgrees(const Pose2& measured, const Pose2& by_odometry, double path_m, double turn_rad,
                    const OdometryGate& gate);
// The same with the odometry at the landmark's creation and now.
bool odometryAgrees(const Pose2& measured, const OdometryAt& created, const OdometryAt& now,
                    const OdometryGate& gate);

}  // namespace vslam
