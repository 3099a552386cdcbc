#pragma once
// Camera images (vslam.image_t) as 8-bit gray for the stages that look at
// pixels: the checks a message must pass and the conversion, each returning
// why it failed (for Bus::reportMalformed) instead of reporting itself, so
// they can run off the stage's thread (the front-end's prefetch).

#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vslam/image_t.hpp>

#include "config/robot_config.hpp"

namespace vslam::stages {

// Size against the camera's calibration, a known encoding, and enough data
// for height x row_stride (raw encodings; a JPEG is checked when decoded).
std::optional<std::string> checkImage(const config::CameraConfig& camera,
                                      const vslam::image_t& msg);

// The pixels of an image as 8-bit gray in *gray (its storage reused):
// copied, converted from BGR, or decoded from JPEG (which must decode to the
// announced size). The raw encodings' sizes are checked here too, so an
// unchecked message is refused, not read past its data.
std::optional<std::string> imageToGray(const vslam::image_t& msg, cv::Mat* gray);

}  // namespace vslam::stages
