#pragma once
// Conversions between configuration/domain types and messages that more than
// one program builds.

#include <vslam/camera_calibration_t.hpp>

#include "config/robot_config.hpp"
#include "util/time.hpp"

namespace vslam::bus {

// The calibration message a camera driver publishes for `camera`.
vslam::camera_calibration_t calibrationMessage(const config::CameraConfig& camera, Utime utime);

}  // namespace vslam::bus
