#include "stages/image_gray.hpp"

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

namespace vslam::stages {
namespace {

// Why the pixels of a raw (gray8, bgr8) image cannot be read as announced.
std::optional<std::string> rawDataProblem(const vslam::image_t& msg, int channels) {
  if (msg.width <= 0 || msg.height <= 0) {
    return "image size " + std::to_string(msg.width) + "x" + std::to_string(msg.height);
  }
  if (msg.row_stride < static_cast<int64_t>(msg.width) * channels ||
      msg.data.size() < static_cast<size_t>(msg.height) * static_cast<size_t>(msg.row_stride)) {
    return std::string("image data shorter than height x row_stride");
  }
  return std::nullopt;
}

}  // namespace

std::optional<std::string> checkImage(const config::CameraConfig& camera,
                                      const vslam::image_t& msg) {
  if (msg.width != camera.width || msg.height != camera.height) {
    return "image " + std::to_string(msg.width) + "x" + std::to_string(msg.height) +
           ", but camera '" + camera.name + "' is calibrated for " + std::to_string(camera.width) +
           "x" + std::to_string(camera.height);
  }
  switch (msg.encoding) {
    case vslam::image_t::ENCODING_GRAY8:
    case vslam::image_t::ENCODING_BGR8: {
      return rawDataProblem(msg, msg.encoding == vslam::image_t::ENCODING_GRAY8 ? 1 : 3);
    }
    case vslam::image_t::ENCODING_JPEG:
      return std::nullopt;  // checked when decoded
    default:
      return "unknown encoding " + std::to_string(msg.encoding);
  }
}

std::optional<std::string> imageToGray(const vslam::image_t& msg, cv::Mat* gray) {
  if (msg.encoding == vslam::image_t::ENCODING_JPEG) {
    *gray = cv::imdecode(msg.data, cv::IMREAD_GRAYSCALE);
    if (gray->empty() || gray->cols != msg.width || gray->rows != msg.height) {
      return std::string("JPEG does not decode to the announced size");
    }
    return std::nullopt;
  }
  const bool is_gray = msg.encoding == vslam::image_t::ENCODING_GRAY8;
  if (!is_gray && msg.encoding != vslam::image_t::ENCODING_BGR8) {
    return "unknown encoding " + std::to_string(msg.encoding);
  }
  // Checked again here: the view below reads height x row_stride bytes.
  if (auto problem = rawDataProblem(msg, is_gray ? 1 : 3)) return problem;
  const cv::Mat view(msg.height, msg.width, is_gray ? CV_8UC1 : CV_8UC3,
                     const_cast<uint8_t*>(msg.data.data()), static_cast<size_t>(msg.row_stride));
  if (is_gray) {
    view.copyTo(*gray);
  } else {
    cv::cvtColor(view, *gray, cv::COLOR_BGR2GRAY);
  }
  return std::nullopt;
}

}  // namespace vslam::stages
