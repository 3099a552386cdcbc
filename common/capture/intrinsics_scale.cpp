#include "capture/intrinsics_scale.hpp"

#include <stdexcept>

namespace vslam::capture {

config::CameraConfig rescaleIntrinsics(const config::CameraConfig& camera, int width, int height) {
  if (camera.width <= 0 || camera.height <= 0 || width <= 0 || height <= 0) {
    throw std::invalid_argument("rescaleIntrinsics: sizes must be positive");
  }
  const double sx = static_cast<double>(width) / camera.width;
  const double sy = static_cast<double>(height) / camera.height;
  config::CameraConfig out = camera;
  out.width = width;
  out.height = height;
  out.fx = camera.fx * sx;
  out.fy = camera.fy * sy;
  out.cx = (camera.cx + 0.5) * sx - 0.5;
  out.cy = (camera.cy + 0.5) * sy - 0.5;
  return out;
}

}  // namespace vslam::capture
