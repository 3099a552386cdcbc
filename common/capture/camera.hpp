#pragma once
// A FrameSource made safe to publish from: frames in robot time that only
// ever move forward, consecutive sequence numbers, a source that goes away
// (end of a recording without loop, read errors, deleted files, an unplugged
// device) reopened with bounded exponential back-off, recordings paced to
// real time (or `speed` x) and optionally looped, an optional resize and
// rate limit, and counters for health. No LCM.

#include <condition_variable>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include "capture/frame_source.hpp"
#include "util/alternation.hpp"

namespace vslam::capture {

struct CameraParams {
  int width = 0;       // output size, pixels; 0 (both): the source's own
  int height = 0;      //
  double max_fps = 0;  // frames closer than 0.9 / max_fps to the last one are dropped; 0: no limit
  // Taking turns with other cameras (needs max_fps): only the first frame
  // whose time falls in this camera's slot of each slots / max_fps period.
  Alternation alternate;
  // Recordings: pace frames at `speed` x their own rate; 0: as fast as they
  // decode. Frame times are the recording's times either way.
  double speed = 1.0;
  bool loop = false;               // recordings: start again at the end
  double reopen_initial_s = 0.1;   // first wait before reopening a lost source...
  double reopen_max_s = 5.0;       // ...doubling up to this
  int max_consecutive_errors = 3;  // read errors in a row that mean the source is gone
};

struct Frame {
  cv::Mat image;             // CV_8UC3 (BGR) or CV_8UC1, at outputSize()
  Utime utime = 0;           // capture time, robot clock (microseconds since the Unix epoch)
  int64_t seq = 0;           // +1 per frame this camera emitted
  int64_t source_index = 0;  // the frame's position in its source
};

enum class SourceState {
  kOpen,       // delivering frames
  kReopening,  // lost; reopened with back-off
  kStopped,    // stop() was called
};
const char* sourceStateName(SourceState state);

// Totals since construction.
struct CameraCounters {
  int64_t frames = 0;           // emitted
  int64_t dropped_stale = 0;    // time not after the last emitted one: repeated or backwards
  int64_t dropped_rate = 0;     // over max_fps
  int64_t dropped_turn = 0;     // alternating: not this camera's turn
  int64_t read_errors = 0;      // reads that failed (a missing or undecodable file, a driver error)
  int64_t sources_lost = 0;     // times the source went away
  int64_t reopen_attempts = 0;  // tries to open it again...
  int64_t reopens = 0;          // ...that succeeded
  int64_t laps = 0;             // loops of a recording completed
};

class Camera {
 public:
  // Opens the source again after a loss; throws (SourceError or other) if it cannot.
  using Opener = std::function<std::unique_ptr<FrameSource>()>;

  // `source`: the already opened source (checked by the caller at start-up).
  Camera(std::unique_ptr<FrameSource> source, Opener reopen, CameraParams params);
  ~Camera();
  Camera(const Camera&) = delete;
  Camera& operator=(const Camera&) = delete;

  enum class Result { kFrame, kTimeout, kStopped };
  // The next frame; waits (pacing a recording, backing off a lost source) at
  // most about max_wait_s beyond one blocking read of the source.
  Result next(Frame* out, double max_wait_s);
  // Ends next()'s waits and makes it return kStopped from now on. Thread-safe.
  void stop();

  // Thread-safe snapshots for health.
  CameraCounters counters() const;
  SourceState state() const;
  std::string lastProblem() const;  // why the source was last lost ("" if never)

  // The size frames come out at (the source's native size if no resize and
  // the source does not know its size before reading: 0x0).
  cv::Size outputSize() const;

 private:
  Result readOne(Frame* out, bool* got);
  void markLost(const std::string& why);
  bool tryReopen();
  // Waits until `deadline_us` (monotonic) or stop(); false if stopped.
  bool waitUntil(Utime deadline_us);
  Utime robotTime(const SourceFrame& f);

  std::unique_ptr<FrameSource> source_;
  Opener reopen_;
  const CameraParams params_;
  const Utime wall_minus_monotonic_;      // robot (wall) clock from the monotonic clock
  std::optional<AlternationGate> turns_;  // params_.alternate, if active

  // Replay pacing and times: the first frame's media time, the monotonic and
  // robot time it was emitted at, and the offset of the current lap.
  bool have_media_origin_ = false;
  Utime media_origin_us_ = 0;
  Utime monotonic_origin_us_ = 0;
  Utime robot_origin_us_ = 0;
  Utime lap_offset_us_ = 0;
  Utime last_media_us_ = -1;          // last frame read in this lap (media time)
  Utime last_emitted_media_us_ = -1;  // within this lap, for seekAfter on a reopen

  Utime last_emitted_utime_ = 0;
  bool emitted_any_ = false;
  bool emitted_since_open_ = false;  // since the source was last (re)opened
  int64_t next_seq_ = 0;
  int consecutive_errors_ = 0;
  double reopen_delay_s_ = 0;
  Utime next_reopen_us_ = 0;

  mutable std::mutex mutex_;  // guards what the snapshot accessors read, and stop_
  std::condition_variable wake_;
  bool stop_ = false;
  SourceState state_ = SourceState::kOpen;
  CameraCounters counters_;
  std::string last_problem_;
  cv::Size native_size_;
};

}  // namespace vslam::capture
