#pragma once
// Frames as the bytes of vslam.image_t (lcmtypes/vslam_image_t.lcm), without
// LCM: the stage copies these fields into the message.

#include <cstdint>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace vslam::capture {

// Values equal vslam::image_t::ENCODING_* (the stage checks it at compile time).
enum class PixelEncoding : int8_t { kGray8 = 0, kBgr8 = 1, kJpeg = 2 };

PixelEncoding parsePixelEncoding(const std::string& name);  // "gray8", "bgr8", "jpeg"
const char* pixelEncodingName(PixelEncoding encoding);

struct EncodedImage {
  int width = 0;       // pixels
  int height = 0;      // pixels
  int row_stride = 0;  // bytes per row of raw encodings; 0 for JPEG
  PixelEncoding encoding = PixelEncoding::kGray8;
  std::vector<uint8_t> data;  // storage reused across calls
};

// `image`: CV_8UC1 or CV_8UC3 (BGR). Converts gray <-> BGR as needed; a JPEG
// keeps the image's channels. Throws std::invalid_argument for other types.
void encodeImage(const cv::Mat& image, PixelEncoding encoding, int jpeg_quality, EncodedImage* out);

}  // namespace vslam::capture
