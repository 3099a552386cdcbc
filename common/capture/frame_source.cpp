#include "capture/frame_source.hpp"

#include <cmath>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/videoio.hpp>
#include <sstream>

#include "capture/image_folder.hpp"

namespace vslam::capture {
namespace fs = std::filesystem;

SourceSpec SourceSpec::parse(const std::string& text) {
  const auto colon = text.find(':');
  if (colon == std::string::npos || colon + 1 >= text.size()) {
    throw SourceError("source", "'" + text +
                                    "' is not a source: give v4l2:/dev/videoN, "
                                    "gstreamer:PIPELINE, video:FILE or folder:DIR");
  }
  const std::string kind = text.substr(0, colon);
  SourceSpec spec;
  spec.location = text.substr(colon + 1);
  if (kind == "v4l2") {
    spec.kind = Kind::kV4l2;
  } else if (kind == "gstreamer") {
    spec.kind = Kind::kGStreamer;
  } else if (kind == "video") {
    spec.kind = Kind::kVideo;
  } else if (kind == "folder") {
    spec.kind = Kind::kFolder;
  } else {
    throw SourceError("source",
                      "unknown source kind '" + kind + "' (known: v4l2, gstreamer, video, folder)");
  }
  return spec;
}

std::string SourceSpec::describe() const {
  switch (kind) {
    case Kind::kV4l2:
      return "v4l2:" + location;
    case Kind::kGStreamer:
      return "gstreamer:" + location;
    case Kind::kVideo:
      return "video:" + location;
    case Kind::kFolder:
      return "folder:" + location;
  }
  return location;
}

bool openCvHasGStreamer() {
  std::istringstream info(cv::getBuildInformation());
  std::string line;
  while (std::getline(info, line)) {
    const auto pos = line.find("GStreamer:");
    if (pos != std::string::npos) return line.find("YES", pos) != std::string::npos;
  }
  return false;
}

namespace {

std::string fourccText(double value) {
  const auto code = static_cast<uint32_t>(value);
  std::string s;
  for (int i = 0; i < 4; ++i) {
    const char c = static_cast<char>((code >> (8 * i)) & 0xff);
    s += (c >= 32 && c < 127) ? c : '?';
  }
  return s;
}

std::string number(double v) {
  std::ostringstream os;
  os << v;
  return os.str();
}

// Host monotonic time at grab, unless the driver's buffer time (on the same
// clock for V4L2 drivers that flag their buffers monotonic) is plausible.
Utime grabTime(const cv::VideoCapture& cap, bool driver_time_on_monotonic_clock) {
  const Utime host = monotonicUtime();
  if (!driver_time_on_monotonic_clock) return host;
  const double ms = cap.get(cv::CAP_PROP_POS_MSEC);
  const auto driver = static_cast<Utime>(std::llround(ms * 1000.0));
  // A driver stamping with another clock (or not at all) is far from now.
  constexpr Utime kMaxSkewUs = kMicrosPerSecond;
  return std::isfinite(ms) && ms > 0 && std::llabs(host - driver) < kMaxSkewUs ? driver : host;
}

// A live device or pipeline through cv::VideoCapture.
class LiveSource final : public FrameSource {
 public:
  LiveSource(cv::VideoCapture cap, bool driver_time, std::vector<std::string> refused)
      : cap_(std::move(cap)), driver_time_(driver_time), refused_(std::move(refused)) {
    size_ = {static_cast<int>(cap_.get(cv::CAP_PROP_FRAME_WIDTH)),
             static_cast<int>(cap_.get(cv::CAP_PROP_FRAME_HEIGHT))};
    fps_ = cap_.get(cv::CAP_PROP_FPS);
    if (!std::isfinite(fps_) || fps_ < 0) fps_ = 0;
  }
  TimeBase timeBase() const override { return TimeBase::kHostMonotonic; }
  ReadStatus read(SourceFrame* out, std::string* error) override {
    if (!cap_.grab()) {
      *error = "the device delivered no frame (unplugged, or a driver error)";
      return ReadStatus::kError;
    }
    const Utime t = grabTime(cap_, driver_time_);
    if (!cap_.retrieve(out->image) || out->image.empty()) {
      *error = "a frame could not be decoded";
      return ReadStatus::kError;
    }
    out->time_us = t;
    out->index = index_++;
    return ReadStatus::kFrame;
  }
  cv::Size nativeSize() const override { return size_; }
  double nominalFps() const override { return fps_; }
  std::vector<std::string> refusedSettings() const override { return refused_; }

 private:
  cv::VideoCapture cap_;
  bool driver_time_;
  std::vector<std::string> refused_;
  cv::Size size_;
  double fps_ = 0;
  int64_t index_ = 0;
};

std::unique_ptr<FrameSource> openV4l2(const SourceSpec& spec) {
  std::error_code ec;
  if (!fs::exists(spec.location, ec)) {
    throw SourceError("source", "no device " + spec.location + " (ls /dev/video* lists cameras)");
  }
  cv::VideoCapture cap;
  if (!cap.open(spec.location, cv::CAP_V4L2) || !cap.isOpened()) {
    throw SourceError("source", spec.location + " cannot be opened as a V4L2 capture device");
  }
  const V4l2Settings& s = spec.v4l2;
  std::vector<std::string> refused;
  // Asks for a property and reads back what the device took.
  auto apply = [&](const std::string& name, int prop, double value, double tolerance) {
    const bool accepted = cap.set(prop, value);
    const double actual = cap.get(prop);
    if (!accepted || !(std::abs(actual - value) <= tolerance)) {
      refused.push_back(name + ": asked " + number(value) + ", device has " + number(actual));
      return false;
    }
    return true;
  };
  if (!s.fourcc.empty()) {
    if (s.fourcc.size() != 4) {
      throw SourceError("v4l2.fourcc", "'" + s.fourcc + "' is not a four-character code");
    }
    const int code = cv::VideoWriter::fourcc(s.fourcc[0], s.fourcc[1], s.fourcc[2], s.fourcc[3]);
    cap.set(cv::CAP_PROP_FOURCC, code);
    const std::string actual = fourccText(cap.get(cv::CAP_PROP_FOURCC));
    if (actual != s.fourcc)
      refused.push_back("fourcc: asked " + s.fourcc + ", device has " + actual);
  }
  if (s.width > 0 || s.height > 0) {
    if (s.width > 0) cap.set(cv::CAP_PROP_FRAME_WIDTH, s.width);
    if (s.height > 0) cap.set(cv::CAP_PROP_FRAME_HEIGHT, s.height);
    const int w = static_cast<int>(cap.get(cv::CAP_PROP_FRAME_WIDTH));
    const int h = static_cast<int>(cap.get(cv::CAP_PROP_FRAME_HEIGHT));
    if ((s.width > 0 && w != s.width) || (s.height > 0 && h != s.height)) {
      throw SourceError(s.width > 0 && w != s.width ? "v4l2.width" : "v4l2.height",
                        spec.location + " cannot give " + std::to_string(s.width) + "x" +
                            std::to_string(s.height) + " (it chose " + std::to_string(w) + "x" +
                            std::to_string(h) + "; v4l2-ctl --list-formats-ext lists its modes)");
    }
  }
  if (s.fps > 0) apply("fps", cv::CAP_PROP_FPS, s.fps, 0.01 * s.fps);
  // V4L2's exposure_auto menu: 1 manual, 3 aperture priority (automatic).
  if (s.auto_exposure)
    apply("auto_exposure", cv::CAP_PROP_AUTO_EXPOSURE, *s.auto_exposure ? 3 : 1, 0);
  if (s.exposure) apply("exposure", cv::CAP_PROP_EXPOSURE, *s.exposure, 0.5);
  if (s.gain) apply("gain", cv::CAP_PROP_GAIN, *s.gain, 0.5);
  return std::make_unique<LiveSource>(std::move(cap), true, std::move(refused));
}

std::unique_ptr<FrameSource> openGStreamer(const SourceSpec& spec) {
  if (!openCvHasGStreamer()) {
    throw SourceError("source",
                      "this OpenCV was built without GStreamer (cv::getBuildInformation() says "
                      "GStreamer: NO): gstreamer sources are not available");
  }
  if (spec.location.find("appsink") == std::string::npos) {
    throw SourceError("source",
                      "a GStreamer pipeline must end in appsink, e.g. "
                      "gstreamer:v4l2src ! videoconvert ! appsink");
  }
  cv::VideoCapture cap;
  if (!cap.open(spec.location, cv::CAP_GSTREAMER) || !cap.isOpened()) {
    throw SourceError("source", "GStreamer pipeline '" + spec.location +
                                    "' does not start (missing plugins? try it with "
                                    "gst-launch-1.0, fakesink for appsink)");
  }
  // Pipeline times are stream-relative: host time at grab.
  return std::make_unique<LiveSource>(std::move(cap), false, std::vector<std::string>{});
}

// A video file: times from the container, paced and looped by Camera.
class VideoFileSource final : public FrameSource {
 public:
  explicit VideoFileSource(const std::string& file) : file_(file) {
    std::error_code ec;
    if (!fs::is_regular_file(file, ec)) throw SourceError("source", "no video file " + file);
    if (!cap_.open(file, cv::CAP_FFMPEG) && !cap_.open(file, cv::CAP_ANY)) {
      throw SourceError("source", file + " cannot be opened as a video");
    }
    size_ = {static_cast<int>(cap_.get(cv::CAP_PROP_FRAME_WIDTH)),
             static_cast<int>(cap_.get(cv::CAP_PROP_FRAME_HEIGHT))};
    fps_ = cap_.get(cv::CAP_PROP_FPS);
    if (!std::isfinite(fps_) || fps_ <= 0 || fps_ > 1000) fps_ = 0;
  }
  TimeBase timeBase() const override { return TimeBase::kMedia; }
  ReadStatus read(SourceFrame* out, std::string* error) override {
    (void)error;
    // A truncated file ends early: decoders cannot tell that from its end.
    if (!cap_.read(out->image) || out->image.empty()) return ReadStatus::kEndOfStream;
    // The container's time of this frame; the frame rate where it has none.
    const double ms = cap_.get(cv::CAP_PROP_POS_MSEC);
    Utime t = std::isfinite(ms) ? static_cast<Utime>(std::llround(ms * 1000.0)) : -1;
    if (t <= last_us_ && index_ > 0) {
      const double period = fps_ > 0 ? 1.0 / fps_ : 0.1;
      t = last_us_ + fromSeconds(period);
    }
    out->time_us = std::max<Utime>(t, 0);
    out->index = index_++;
    last_us_ = out->time_us;
    return ReadStatus::kFrame;
  }
  cv::Size nativeSize() const override { return size_; }
  double nominalFps() const override { return fps_; }
  void seekAfter(Utime time_us) override {
    // Decoding forward is exact where seeking in compressed video is not.
    // Stops at the frame at time_us itself (within half a frame: rounding).
    const Utime half_period = fromSeconds(fps_ > 0 ? 0.5 / fps_ : 0.05);
    while (last_us_ + half_period < time_us && cap_.grab()) {
      const double ms = cap_.get(cv::CAP_PROP_POS_MSEC);
      if (!std::isfinite(ms)) return;
      ++index_;
      last_us_ = static_cast<Utime>(std::llround(ms * 1000.0));
    }
  }

 private:
  std::string file_;
  cv::VideoCapture cap_;
  cv::Size size_;
  double fps_ = 0;
  int64_t index_ = 0;
  Utime last_us_ = -1;
};

class ImageFolderSource final : public FrameSource {
 public:
  explicit ImageFolderSource(const std::string& location) {
    std::error_code ec;
    fs::path list = location;
    if (fs::is_directory(list, ec)) list /= "rgb.txt";
    entries_ = readTimestampsFile(list);
    if (entries_.size() > 1) {
      const double span = toSeconds(entries_.back().time_us - entries_.front().time_us);
      fps_ = static_cast<double>(entries_.size() - 1) / span;
    }
    // The first image that reads gives the size (0x0 if none does yet).
    for (const auto& e : entries_) {
      if (!fs::is_regular_file(e.file, ec)) continue;
      const cv::Mat first = cv::imread(e.file.string(), cv::IMREAD_ANYCOLOR);
      if (!first.empty()) {
        size_ = first.size();
        break;
      }
    }
  }
  TimeBase timeBase() const override { return TimeBase::kMedia; }
  ReadStatus read(SourceFrame* out, std::string* error) override {
    if (next_ >= entries_.size()) return ReadStatus::kEndOfStream;
    const TimestampedImage& e = entries_[next_];
    out->index = static_cast<int64_t>(next_++);
    std::error_code ec;
    if (!fs::is_regular_file(e.file, ec)) {
      *error = e.file.string() + " is missing";
      return ReadStatus::kError;
    }
    out->image = cv::imread(e.file.string(), cv::IMREAD_ANYCOLOR);  // 8-bit, gray or BGR
    if (out->image.empty() || (out->image.type() != CV_8UC1 && out->image.type() != CV_8UC3)) {
      *error = e.file.string() + " is not a readable 8-bit gray or colour image";
      return ReadStatus::kError;
    }
    out->time_us = e.time_us - entries_.front().time_us;
    return ReadStatus::kFrame;
  }
  cv::Size nativeSize() const override { return size_; }
  double nominalFps() const override { return fps_; }
  void seekAfter(Utime time_us) override {
    while (next_ < entries_.size() &&
           entries_[next_].time_us - entries_.front().time_us <= time_us) {
      ++next_;
    }
  }

 private:
  std::vector<TimestampedImage> entries_;
  size_t next_ = 0;
  cv::Size size_;
  double fps_ = 0;
};

}  // namespace

std::unique_ptr<FrameSource> openSource(const SourceSpec& spec) {
  switch (spec.kind) {
    case SourceSpec::Kind::kV4l2:
      return openV4l2(spec);
    case SourceSpec::Kind::kGStreamer:
      return openGStreamer(spec);
    case SourceSpec::Kind::kVideo:
      return std::make_unique<VideoFileSource>(spec.location);
    case SourceSpec::Kind::kFolder:
      return std::make_unique<ImageFolderSource>(spec.location);
  }
  throw SourceError("source", "unknown source kind");
}

}  // namespace vslam::capture
