#pragma once
// Frames for vslam-calibrate: a list of image files or an image folder (no
// timestamps needed), or a stream of the camera driver's capture library (a
// video file, a live V4L2 camera). No LCM.

#include <filesystem>
#include <memory>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "capture/frame_source.hpp"

namespace vslam::calibration {

class FrameSource {
 public:
  // Throws std::runtime_error naming the file, folder or device that cannot be read.
  static FrameSource images(std::vector<std::filesystem::path> files);
  // Every image file in the folder (jpg, jpeg, png, bmp, tif, tiff, pgm, ppm), sorted by name.
  static FrameSource folder(const std::filesystem::path& dir);
  static FrameSource video(const std::filesystem::path& file);
  static FrameSource device(int index);

  // The next frame as grey; false at the end. `stride` skips frames of a
  // video or camera (every stride-th is returned). An image file that cannot
  // be decoded throws.
  bool next(cv::Mat* gray, std::string* name, int stride = 1);
  std::string describe() const;

 private:
  FrameSource() = default;
  static FrameSource stream(const capture::SourceSpec& spec, std::string label);
  std::vector<std::filesystem::path> files_;
  size_t next_file_ = 0;
  std::shared_ptr<capture::FrameSource> stream_;  // video or device
  std::string label_;
  int64_t frame_index_ = 0;
};

}  // namespace vslam::calibration
