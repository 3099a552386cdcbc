#pragma once
// Conversions between configuration/domain types and messages that more than
// one program builds.

#include <string>
#include <vslam/camera_calibration_t.hpp>
#include <vslam/health_t.hpp>

#include "bus/stage.hpp"
#include "config/robot_config.hpp"
#include "util/time.hpp"

namespace vslam::bus {

// The calibration message a camera driver publishes for `camera`.
vslam::camera_calibration_t calibrationMessage(const config::CameraConfig& camera, Utime utime);

// A HEALTH message of this process at `utime`: who it is (process, instance,
// pid, uptime since `started_monotonic`), its CPU time and memory, and the
// report's level, message and metrics. Message counters are the caller's.
vslam::health_t healthMessage(const std::string& process, const std::string& instance, Utime utime,
                              Utime started_monotonic, const HealthReport& report);

}  // namespace vslam::bus
