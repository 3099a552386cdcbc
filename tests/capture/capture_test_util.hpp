#pragma once
// Recordings made by the tests: an MJPG video and a PNG folder with an
// rgb.txt, whose frame i has the grey level levelOf(i) (recoverable after
// JPEG compression), and a temporary directory.

#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>
#include <stdexcept>
#include <string>

namespace vslam::capture_test {

namespace fs = std::filesystem;

inline int levelOf(int64_t index) { return 20 + static_cast<int>(index % 20) * 10; }
// The frame index (mod 20) a decoded frame shows.
inline int64_t indexOf(const cv::Mat& image) {
  cv::Mat gray = image;
  if (image.channels() == 3) cv::cvtColor(image, gray, cv::COLOR_BGR2GRAY);
  return std::lround((cv::mean(gray)[0] - 20) / 10.0);
}

inline cv::Mat frameImage(int64_t index, cv::Size size) {
  return cv::Mat(size, CV_8UC3, cv::Scalar::all(levelOf(index)));
}

class TempDir {
 public:
  TempDir() {
    const char* base = std::getenv("TMPDIR");
    std::string pattern = std::string(base && *base ? base : "/tmp") + "/vslam-capture-XXXXXX";
    if (!::mkdtemp(pattern.data())) throw std::runtime_error("mkdtemp failed");
    path_ = pattern;
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

inline void writeVideo(const fs::path& file, int frames, double fps, cv::Size size) {
  cv::VideoWriter writer(file.string(), cv::CAP_FFMPEG, cv::VideoWriter::fourcc('M', 'J', 'P', 'G'),
                         fps, size);
  if (!writer.isOpened()) throw std::runtime_error("cannot write " + file.string());
  for (int i = 0; i < frames; ++i) writer.write(frameImage(i, size));
}

inline std::string imageName(int index) { return "rgb/" + std::to_string(index) + ".png"; }

// PNGs at `start_s` + i * period_s, listed in dir/rgb.txt (with a comment and a blank line).
inline void writeFolder(const fs::path& dir, int frames, double start_s, double period_s,
                        cv::Size size) {
  fs::create_directories(dir / "rgb");
  std::ofstream list(dir / "rgb.txt");
  list << "# color images\n# timestamp filename\n\n";
  for (int i = 0; i < frames; ++i) {
    cv::imwrite((dir / imageName(i)).string(), frameImage(i, size));
    list.precision(17);
    list << start_s + i * period_s << " " << imageName(i) << "\n";
  }
}

}  // namespace vslam::capture_test
