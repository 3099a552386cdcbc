#include "calibration/frame_source.hpp"

#include <algorithm>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <set>
#include <stdexcept>

namespace vslam::calibration {
namespace {

cv::Mat toGray(const cv::Mat& frame) {
  if (frame.channels() == 1) return frame;
  cv::Mat gray;
  cv::cvtColor(frame, gray, frame.channels() == 4 ? cv::COLOR_BGRA2GRAY : cv::COLOR_BGR2GRAY);
  return gray;
}

}  // namespace

FrameSource FrameSource::images(std::vector<std::filesystem::path> files) {
  for (const auto& f : files) {
    if (!std::filesystem::is_regular_file(f))
      throw std::runtime_error("no such image: " + f.string());
  }
  FrameSource s;
  s.label_ = std::to_string(files.size()) + " image files";
  s.files_ = std::move(files);
  return s;
}

FrameSource FrameSource::folder(const std::filesystem::path& dir) {
  if (!std::filesystem::is_directory(dir))
    throw std::runtime_error("no such folder: " + dir.string());
  static const std::set<std::string> kExtensions = {".jpg", ".jpeg", ".png", ".bmp",
                                                    ".tif", ".tiff", ".pgm", ".ppm"};
  std::vector<std::filesystem::path> files;
  for (const auto& entry : std::filesystem::directory_iterator(dir)) {
    std::string ext = entry.path().extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(),
                   [](unsigned char c) { return std::tolower(c); });
    if (entry.is_regular_file() && kExtensions.count(ext)) files.push_back(entry.path());
  }
  if (files.empty()) throw std::runtime_error("no image files in " + dir.string());
  std::sort(files.begin(), files.end());
  FrameSource s = images(std::move(files));
  s.label_ = "folder " + dir.string() + " (" + std::to_string(s.files_.size()) + " images)";
  return s;
}

FrameSource FrameSource::stream(const capture::SourceSpec& spec, std::string label) {
  FrameSource s;
  try {
    s.stream_ = capture::openSource(spec);
  } catch (const capture::SourceError& e) {
    throw std::runtime_error(e.what());
  }
  s.label_ = std::move(label);
  return s;
}

FrameSource FrameSource::video(const std::filesystem::path& file) {
  return stream({capture::SourceSpec::Kind::kVideo, file.string(), {}}, "video " + file.string());
}

FrameSource FrameSource::device(int index) {
  const std::string path = "/dev/video" + std::to_string(index);
  return stream({capture::SourceSpec::Kind::kV4l2, path, {}}, "camera " + path);
}

std::string FrameSource::describe() const { return label_; }

bool FrameSource::next(cv::Mat* gray, std::string* name, int stride) {
  if (!stream_) {
    if (next_file_ >= files_.size()) return false;
    const auto& file = files_[next_file_++];
    const cv::Mat image = cv::imread(file.string(), cv::IMREAD_UNCHANGED);
    if (image.empty()) throw std::runtime_error("cannot decode image " + file.string());
    *gray = toGray(image);
    *name = file.filename().string();
    return true;
  }
  // Frames in between are decoded and dropped (a stream does not seek).
  capture::SourceFrame frame;
  std::string error;
  for (int k = 0; k < std::max(stride, 1); ++k) {
    capture::ReadStatus status = capture::ReadStatus::kError;
    for (int errors = 0; status == capture::ReadStatus::kError && errors < 10; ++errors) {
      status = stream_->read(&frame, &error);
    }
    if (status != capture::ReadStatus::kFrame) return false;  // the end, or failing
    ++frame_index_;
  }
  *name = "frame " + std::to_string(frame_index_ - 1);
  *gray = toGray(frame.image);
  return true;
}

}  // namespace vslam::calibration
