#pragma once
// Intrinsics of a camera whose images are resized.

#include "config/robot_config.hpp"

namespace vslam::capture {

// The camera's intrinsics for its images resized to width x height (as
// cv::resize does it: pixel centres map as u' = (u + 0.5) s - 0.5). The lens
// distortion acts on normalized coordinates and is unchanged.
config::CameraConfig rescaleIntrinsics(const config::CameraConfig& camera, int width, int height);

}  // namespace vslam::capture
