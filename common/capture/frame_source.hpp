#pragma once
// Where camera frames come from: a V4L2 device, a GStreamer pipeline, a video
// file or an image folder with a TUM rgb.txt-style timestamps file, behind one
// small interface. Opening checks what it can and throws SourceError naming
// the setting at fault; reading returns a frame, the end of the stream, or an
// error. No LCM: the camera stage (common/stages/camera_stage.hpp) publishes.

#include <filesystem>
#include <memory>
#include <opencv2/core.hpp>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "util/time.hpp"

namespace vslam::capture {

// A source could not be opened or configured. `setting` names what was wrong
// ("source", "v4l2.width", ...), for the caller's configuration error.
class SourceError : public std::runtime_error {
 public:
  SourceError(std::string setting, const std::string& what)
      : std::runtime_error(what), setting_(std::move(setting)) {}
  const std::string& setting() const { return setting_; }

 private:
  std::string setting_;
};

// The capture mode and controls asked of a V4L2 device; unset: the device's own.
struct V4l2Settings {
  int width = 0;       // pixels; 0: the device's current mode
  int height = 0;      // pixels
  double fps = 0;      // frames per second; 0: the device's
  std::string fourcc;  // pixel format, e.g. "MJPG", "YUYV"; "": the device's
  std::optional<bool> auto_exposure;
  std::optional<double> exposure;  // device units (V4L2 exposure_absolute: 100 us)
  std::optional<double> gain;      // device units
};

struct SourceSpec {
  enum class Kind { kV4l2, kGStreamer, kVideo, kFolder };
  Kind kind = Kind::kVideo;
  // Device path, pipeline, video file, or folder (or its timestamps file).
  std::string location;
  V4l2Settings v4l2;  // kV4l2 only

  // "v4l2:/dev/video0", "gstreamer:<pipeline ending in appsink>",
  // "video:<file>", "folder:<dir or timestamps file>". Throws SourceError("source").
  static SourceSpec parse(const std::string& text);
  bool isReplay() const { return kind == Kind::kVideo || kind == Kind::kFolder; }
  std::string describe() const;
};

// The clock of a source's frame times.
enum class TimeBase {
  kHostMonotonic,  // vslam::monotonicUtime()'s clock: driver buffer times, or host time at grab
  kMedia,          // the recording's own timeline, microseconds from its first frame
};

struct SourceFrame {
  cv::Mat image;      // CV_8UC3 (BGR) or CV_8UC1
  Utime time_us = 0;  // on the source's TimeBase
  int64_t index = 0;  // position in the source since it was opened (files: frame / line number)
};

enum class ReadStatus { kFrame, kEndOfStream, kError };

class FrameSource {
 public:
  virtual ~FrameSource() = default;
  virtual TimeBase timeBase() const = 0;
  // Blocks for the next frame (devices: until the driver delivers one).
  // kError: *error says why; the source may still deliver later frames.
  virtual ReadStatus read(SourceFrame* out, std::string* error) = 0;
  // Size of the frames, as far as known after opening (0x0: unknown).
  virtual cv::Size nativeSize() const = 0;
  // Nominal frames per second; 0 if unknown.
  virtual double nominalFps() const = 0;
  // Recordings: continue after media time `time_us` (reopened after a loss:
  // nothing emitted before is read again). Devices: nothing.
  virtual void seekAfter(Utime time_us) { (void)time_us; }
  // Settings the device did not take, each "name: asked X, device has Y".
  virtual std::vector<std::string> refusedSettings() const { return {}; }
};

// Opens a source; throws SourceError naming the setting at fault (a missing
// device or file, a size the device cannot give, GStreamer missing from
// OpenCV's build, ...). Relative file paths are taken as given (the caller
// resolves them against its config file).
std::unique_ptr<FrameSource> openSource(const SourceSpec& spec);

// Whether this OpenCV was built with GStreamer, from cv::getBuildInformation().
bool openCvHasGStreamer();

}  // namespace vslam::capture
