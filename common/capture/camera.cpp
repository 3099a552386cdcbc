#include "capture/camera.hpp"

#include <algorithm>
#include <chrono>
#include <opencv2/imgproc.hpp>

namespace vslam::capture {

const char* sourceStateName(SourceState state) {
  switch (state) {
    case SourceState::kOpen:
      return "open";
    case SourceState::kReopening:
      return "reopening";
    case SourceState::kStopped:
      return "stopped";
  }
  return "?";
}

Camera::Camera(std::unique_ptr<FrameSource> source, Opener reopen, CameraParams params)
    : source_(std::move(source)),
      reopen_(std::move(reopen)),
      params_(params),
      wall_minus_monotonic_(wallUtime() - monotonicUtime()),
      reopen_delay_s_(params.reopen_initial_s) {
  if (!source_) throw std::invalid_argument("Camera: no source");
  if (params_.alternate.active()) {
    if (params_.max_fps <= 0) {
      throw std::invalid_argument("Camera: alternating needs max_fps > 0 (the rate slots share)");
    }
    turns_.emplace(params_.alternate, params_.max_fps);
  }
  native_size_ = source_->nativeSize();
}

Camera::~Camera() = default;

void Camera::stop() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
    state_ = SourceState::kStopped;
  }
  wake_.notify_all();
}

CameraCounters Camera::counters() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return counters_;
}

SourceState Camera::state() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return state_;
}

std::string Camera::lastProblem() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return last_problem_;
}

cv::Size Camera::outputSize() const {
  if (params_.width > 0 && params_.height > 0) return {params_.width, params_.height};
  std::lock_guard<std::mutex> lock(mutex_);
  return native_size_;
}

bool Camera::waitUntil(Utime deadline_us) {
  std::unique_lock<std::mutex> lock(mutex_);
  const Utime now = monotonicUtime();
  if (deadline_us > now) {
    wake_.wait_for(lock, std::chrono::microseconds(deadline_us - now), [this] { return stop_; });
  }
  return !stop_;
}

void Camera::markLost(const std::string& why) {
  source_.reset();
  consecutive_errors_ = 0;
  // A source that comes back but gives nothing new (an ended recording)
  // keeps backing off; one that delivered resets the back-off.
  reopen_delay_s_ = emitted_since_open_ ? params_.reopen_initial_s
                                        : std::min(2 * reopen_delay_s_, params_.reopen_max_s);
  if (reopen_delay_s_ <= 0) reopen_delay_s_ = params_.reopen_initial_s;
  next_reopen_us_ = monotonicUtime() + fromSeconds(reopen_delay_s_);
  std::lock_guard<std::mutex> lock(mutex_);
  ++counters_.sources_lost;
  last_problem_ = why;
  if (state_ != SourceState::kStopped) state_ = SourceState::kReopening;
}

bool Camera::tryReopen() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    ++counters_.reopen_attempts;
  }
  std::unique_ptr<FrameSource> source;
  try {
    source = reopen_();
  } catch (const std::exception& e) {
    reopen_delay_s_ = std::min(2 * reopen_delay_s_, params_.reopen_max_s);
    next_reopen_us_ = monotonicUtime() + fromSeconds(reopen_delay_s_);
    std::lock_guard<std::mutex> lock(mutex_);
    last_problem_ = std::string("cannot reopen: ") + e.what();
    return false;
  }
  if (!source) return false;
  // A recording resumes after what this lap already emitted.
  if (source->timeBase() == TimeBase::kMedia && last_emitted_media_us_ >= 0) {
    source->seekAfter(last_emitted_media_us_);
  }
  source_ = std::move(source);
  emitted_since_open_ = false;
  std::lock_guard<std::mutex> lock(mutex_);
  ++counters_.reopens;
  native_size_ = source_->nativeSize();
  if (state_ != SourceState::kStopped) state_ = SourceState::kOpen;
  return true;
}

Utime Camera::robotTime(const SourceFrame& f) {
  if (source_->timeBase() == TimeBase::kHostMonotonic) return f.time_us + wall_minus_monotonic_;
  if (!have_media_origin_) {
    have_media_origin_ = true;
    media_origin_us_ = f.time_us;
    robot_origin_us_ = wallUtime();
    monotonic_origin_us_ = monotonicUtime();
  }
  return robot_origin_us_ + lap_offset_us_ + (f.time_us - media_origin_us_);
}

Camera::Result Camera::readOne(Frame* out, bool* got) {
  *got = false;
  SourceFrame f;
  std::string error;
  const bool media = source_->timeBase() == TimeBase::kMedia;
  switch (source_->read(&f, &error)) {
    case ReadStatus::kError: {
      {
        std::lock_guard<std::mutex> lock(mutex_);
        ++counters_.read_errors;
        last_problem_ = error;
      }
      if (++consecutive_errors_ >= params_.max_consecutive_errors) markLost(error);
      return Result::kTimeout;
    }
    case ReadStatus::kEndOfStream: {
      if (!params_.loop || !media) {
        markLost("end of stream");
        return Result::kTimeout;
      }
      if (last_media_us_ < 0) {
        markLost("a lap without any frame");
        return Result::kTimeout;
      }
      // The next lap follows this one by a frame period: times keep rising.
      const double fps = source_->nominalFps();
      lap_offset_us_ += last_media_us_ - media_origin_us_ + fromSeconds(fps > 0 ? 1.0 / fps : 0.1);
      last_media_us_ = -1;
      last_emitted_media_us_ = -1;
      try {
        source_ = reopen_();
      } catch (const std::exception& e) {
        markLost(std::string("cannot restart the loop: ") + e.what());
        return Result::kTimeout;
      }
      std::lock_guard<std::mutex> lock(mutex_);
      ++counters_.laps;
      return Result::kTimeout;
    }
    case ReadStatus::kFrame:
      break;
  }
  consecutive_errors_ = 0;
  if (media) last_media_us_ = std::max(last_media_us_, f.time_us);
  const Utime utime = robotTime(f);
  if (emitted_any_ && utime <= last_emitted_utime_) {
    std::lock_guard<std::mutex> lock(mutex_);
    ++counters_.dropped_stale;
    return Result::kTimeout;
  }
  if (turns_) {
    // Taking turns replaces the rate limit: one frame per period, in its slot.
    if (!turns_->take(utime)) {
      std::lock_guard<std::mutex> lock(mutex_);
      ++counters_.dropped_turn;
      return Result::kTimeout;
    }
  } else if (params_.max_fps > 0 && emitted_any_ &&
             toSeconds(utime - last_emitted_utime_) < 0.9 / params_.max_fps) {
    std::lock_guard<std::mutex> lock(mutex_);
    ++counters_.dropped_rate;
    return Result::kTimeout;
  }
  if (media && params_.speed > 0) {
    const double since_origin_s = toSeconds(utime - robot_origin_us_) / params_.speed;
    if (!waitUntil(monotonic_origin_us_ + fromSeconds(since_origin_s))) return Result::kStopped;
  }
  if (params_.width > 0 && params_.height > 0 &&
      (f.image.cols != params_.width || f.image.rows != params_.height)) {
    const bool shrink = f.image.cols > params_.width;
    cv::resize(f.image, out->image, {params_.width, params_.height}, 0, 0,
               shrink ? cv::INTER_AREA : cv::INTER_LINEAR);
  } else {
    out->image = f.image;
  }
  out->utime = utime;
  out->seq = next_seq_++;
  out->source_index = f.index;
  last_emitted_utime_ = utime;
  emitted_any_ = true;
  emitted_since_open_ = true;
  if (media) last_emitted_media_us_ = f.time_us;
  std::lock_guard<std::mutex> lock(mutex_);
  ++counters_.frames;
  if (params_.width <= 0 || params_.height <= 0) native_size_ = f.image.size();
  *got = true;
  return Result::kFrame;
}

Camera::Result Camera::next(Frame* out, double max_wait_s) {
  const Utime deadline = monotonicUtime() + fromSeconds(max_wait_s);
  for (;;) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (stop_) return Result::kStopped;
    }
    if (!source_) {
      const Utime now = monotonicUtime();
      if (now < next_reopen_us_) {
        if (now >= deadline) return Result::kTimeout;
        if (!waitUntil(std::min(next_reopen_us_, deadline))) return Result::kStopped;
        continue;
      }
      if (!tryReopen()) continue;
    }
    bool got = false;
    if (readOne(out, &got) == Result::kStopped) return Result::kStopped;
    if (got) return Result::kFrame;
    if (monotonicUtime() >= deadline) return Result::kTimeout;
  }
}

}  // namespace vslam::capture
