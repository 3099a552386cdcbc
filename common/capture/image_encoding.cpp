#include "capture/image_encoding.hpp"

#include <cstring>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

namespace vslam::capture {

PixelEncoding parsePixelEncoding(const std::string& name) {
  if (name == "gray8") return PixelEncoding::kGray8;
  if (name == "bgr8") return PixelEncoding::kBgr8;
  if (name == "jpeg") return PixelEncoding::kJpeg;
  throw std::invalid_argument("unknown encoding '" + name + "' (known: gray8, bgr8, jpeg)");
}

const char* pixelEncodingName(PixelEncoding encoding) {
  switch (encoding) {
    case PixelEncoding::kGray8:
      return "gray8";
    case PixelEncoding::kBgr8:
      return "bgr8";
    case PixelEncoding::kJpeg:
      return "jpeg";
  }
  return "?";
}

void encodeImage(const cv::Mat& image, PixelEncoding encoding, int jpeg_quality,
                 EncodedImage* out) {
  if (image.empty() || (image.type() != CV_8UC1 && image.type() != CV_8UC3)) {
    throw std::invalid_argument("encodeImage: an 8-bit gray or BGR image is needed");
  }
  out->width = image.cols;
  out->height = image.rows;
  out->encoding = encoding;
  if (encoding == PixelEncoding::kJpeg) {
    out->row_stride = 0;
    cv::imencode(".jpg", image, out->data, {cv::IMWRITE_JPEG_QUALITY, jpeg_quality});
    return;
  }
  const int channels = encoding == PixelEncoding::kGray8 ? 1 : 3;
  cv::Mat converted;
  const cv::Mat* src = &image;
  if (image.channels() != channels) {
    cv::cvtColor(image, converted, channels == 1 ? cv::COLOR_BGR2GRAY : cv::COLOR_GRAY2BGR);
    src = &converted;
  }
  out->row_stride = image.cols * channels;
  const size_t row_bytes = static_cast<size_t>(out->row_stride);
  out->data.resize(row_bytes * static_cast<size_t>(image.rows));
  for (int r = 0; r < image.rows; ++r) {
    std::memcpy(out->data.data() + static_cast<size_t>(r) * row_bytes, src->ptr(r), row_bytes);
  }
}

}  // namespace vslam::capture
