#pragma once
// Camera images (vslam.image_t) as 8-bit gray for the stages that look at
// pixels: the checks a message must pass and the conversion, each returning
// why it failed (for Bus::reportMalformed) instead of reporting itself, so
// they can run off the stage's thread (the front-end's prefetch).

#include <cstddef>
#include <cstdint>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vslam/image_t.hpp>

#include "config/robot_config.hpp"

namespace vslam::stages {

// What a JPEG's header announces (its frame header, SOF).
struct JpegHeader {
  int width = 0;
  int height = 0;
  int components = 0;  // 1 gray, 3 color
};

// Reads the header of the JPEG in data[0, size) into *header without
// decoding or allocating the image (libjpeg's jpeg_read_header, which stops
// at the first scan). Why not, for bytes that are not a JPEG, a header that is
// truncated or malformed (libjpeg's warnings included), or an image that does
// not end with its end-of-image marker (truncated data would decode to gray).
std::optional<std::string> readJpegHeader(const uint8_t* data, size_t size, JpegHeader* header);

// Size against the camera's calibration, a known encoding, and enough data
// for height x row_stride (raw encodings); a JPEG's header must announce the
// message's size (readJpegHeader), so that a hostile one is refused before
// anything decodes it.
std::optional<std::string> checkImage(const config::CameraConfig& camera,
                                      const vslam::image_t& msg);

// The pixels of an image as 8-bit gray in *gray (its storage reused):
// copied, converted from BGR, or decoded from JPEG (refused when its scan
// data is damaged: libjpeg's warnings in the scan). The sizes are checked
// here too (a raw image's data, a JPEG's header against the message's size
// before decoding), so an unchecked message is refused, not read past its
// data or decoded at a size nobody asked for.
std::optional<std::string> imageToGray(const vslam::image_t& msg, cv::Mat* gray);

}  // namespace vslam::stages
