#include "stages/camera_stage.hpp"

#include <vslam/image_t.hpp>

#include "bus/messages.hpp"
#include "capture/intrinsics_scale.hpp"
#include "util/log.hpp"

namespace vslam::stages {

static_assert(static_cast<int8_t>(capture::PixelEncoding::kGray8) ==
                  vslam::image_t::ENCODING_GRAY8 &&
              static_cast<int8_t>(capture::PixelEncoding::kBgr8) == vslam::image_t::ENCODING_BGR8 &&
              static_cast<int8_t>(capture::PixelEncoding::kJpeg) == vslam::image_t::ENCODING_JPEG);

namespace {

std::string sizeText(int width, int height) {
  return std::to_string(width) + "x" + std::to_string(height);
}

// The V4L2 block: capture mode and controls asked of the device.
capture::V4l2Settings loadV4l2(const config::ConfigNode& node) {
  capture::V4l2Settings s;
  s.width = static_cast<int>(node.getInt("width", s.width, config::InRange{0, 16384}));
  s.height = static_cast<int>(node.getInt("height", s.height, config::InRange{0, 16384}));
  s.fps = node.getDouble("fps", s.fps, config::InRange{0, 1000});
  s.fourcc = node.getString("fourcc", s.fourcc);
  if (!s.fourcc.empty() && s.fourcc.size() != 4) {
    throw node.error("fourcc", "'" + s.fourcc + "' is not a four-character code (e.g. MJPG)");
  }
  if (node.has("auto_exposure")) s.auto_exposure = node.getBool("auto_exposure");
  if (node.has("exposure")) s.exposure = node.getDouble("exposure", config::nonNegative());
  if (node.has("gain")) s.gain = node.getDouble("gain", config::nonNegative());
  node.requireAllKeysUsed();
  return s;
}

}  // namespace

CameraStageParams CameraStageParams::load(const config::ConfigNode& node,
                                          const config::RobotConfig& robot) {
  CameraStageParams p;
  const std::string name = node.getString("camera");
  try {
    p.camera = robot.camera(name);
  } catch (const std::out_of_range&) {
    std::string known;
    for (const auto& c : robot.cameras) known += (known.empty() ? "" : ", ") + c.name;
    throw node.error("camera", "no camera '" + name + "' in " + robot.file.string() +
                                   " (it has: " + known + ")");
  }
  try {
    p.source = capture::SourceSpec::parse(node.getString("source"));
  } catch (const capture::SourceError& e) {
    throw node.error("source", e.what());
  }
  if (p.source.isReplay() && std::filesystem::path(p.source.location).is_relative()) {
    p.source.location = (node.baseDir() / p.source.location).lexically_normal().string();
  }
  if (node.has("v4l2")) {
    if (p.source.kind != capture::SourceSpec::Kind::kV4l2) {
      throw node.error("v4l2", "device settings need a v4l2: source");
    }
    p.source.v4l2 = loadV4l2(node.child("v4l2"));
  }
  p.encoding = capture::parsePixelEncoding(
      node.getEnum("encoding", {"gray8", "bgr8", "jpeg"}));  // required: the bus load depends on it
  p.jpeg_quality =
      static_cast<int>(node.getInt("jpeg_quality", p.jpeg_quality, config::InRange{1, 100}));
  capture::CameraParams& c = p.capture;
  c.width = static_cast<int>(node.getInt("width", c.width, config::InRange{0, 16384}));
  c.height = static_cast<int>(node.getInt("height", c.height, config::InRange{0, 16384}));
  if ((c.width == 0) != (c.height == 0)) {
    throw node.error(c.width == 0 ? "width" : "height", "give both width and height, or neither");
  }
  c.max_fps = node.getDouble("max_fps", c.max_fps, config::InRange{0, 1000});
  if (node.has("alternate") && c.max_fps <= 0) {
    throw node.error("alternate", "needs max_fps > 0: the cameras taking turns share that rate");
  }
  c.alternate = config::readAlternation(node, "alternate", c.max_fps);
  c.speed = node.getDouble("speed", c.speed, config::InRange{0, 1000});
  c.loop = node.getBool("loop", c.loop);
  if (!p.source.isReplay()) {
    for (const char* key : {"speed", "loop"}) {
      if (node.has(key)) throw node.error(key, "only for video: and folder: sources");
    }
  }
  c.reopen_initial_s =
      node.getDouble("reopen_initial_s", c.reopen_initial_s, config::InRange{0.001, 60});
  c.reopen_max_s = node.getDouble("reopen_max_s", c.reopen_max_s, config::InRange{0.001, 3600});
  c.max_consecutive_errors = static_cast<int>(
      node.getInt("max_consecutive_errors", c.max_consecutive_errors, config::InRange{1, 1000}));
  p.calibration_period_s =
      node.getDouble("calibration_period_s", p.calibration_period_s, config::InRange{0.1, 60});
  return p;
}

CameraStage::CameraStage(CameraStageParams params, std::unique_ptr<capture::FrameSource> source)
    : params_(std::move(params)), refused_settings_(source->refusedSettings()) {
  const capture::SourceSpec spec = params_.source;
  camera_ = std::make_unique<capture::Camera>(
      std::move(source), [spec] { return capture::openSource(spec); }, params_.capture);
}

CameraStage::~CameraStage() { stop(); }

std::vector<std::string> CameraStage::outputChannels() const {
  return {params_.camera.image_channel, params_.camera.calibration_channel};
}

void CameraStage::start(bus::StageContext& ctx) {
  if (ctx.mode != bus::ExecutionMode::kLive) {
    throw std::logic_error("the camera stage is a live driver; a replay's log is its camera");
  }
  ctx_ = &ctx;
  for (const auto& r : refused_settings_) {
    log::warn(params_.source.describe(), " refused a setting: ", r);
  }
  log::info("camera '", params_.camera.name, "' from ", params_.source.describe(), ", ",
            capture::pixelEncodingName(params_.encoding), " ",
            sizeText(params_.camera.width, params_.camera.height), " on ",
            params_.camera.image_channel);
  const Alternation& turns = params_.capture.alternate;
  if (turns.active()) {
    log::info("camera '", params_.camera.name, "' takes turns: slot ", turns.slot, " of ",
              turns.slots, ", ", params_.capture.max_fps / turns.slots, " Hz");
  }
  onTimer(ctx.clock.now());
  thread_ = std::thread([this] { captureLoop(); });
}

void CameraStage::captureLoop() {
  capture::Frame frame;
  capture::EncodedImage encoded;
  vslam::image_t msg{};
  msg.camera = params_.camera.name;
  msg.exposure = 1.0f;  // nominal: the driver does not report what the device applied
  log::RateLimitedWarnings<1> size_warnings(10 * kMicrosPerSecond);
  for (;;) {
    const auto result = camera_->next(&frame, 0.5);
    if (result == capture::Camera::Result::kStopped) return;
    if (result != capture::Camera::Result::kFrame) continue;
    // A device or folder that changes its size mid-run (no resize asked).
    if (frame.image.cols != params_.camera.width || frame.image.rows != params_.camera.height) {
      ++wrong_size_;
      size_warnings.warn(0, monotonicUtime(), "frame ", frame.seq, " is ",
                         sizeText(frame.image.cols, frame.image.rows), ", but camera '",
                         params_.camera.name, "' is calibrated for ",
                         sizeText(params_.camera.width, params_.camera.height), ": dropped");
      continue;
    }
    capture::encodeImage(frame.image, params_.encoding, params_.jpeg_quality, &encoded);
    msg.utime = frame.utime;
    msg.seq = frame.seq;
    msg.width = encoded.width;
    msg.height = encoded.height;
    msg.row_stride = encoded.row_stride;
    msg.encoding = static_cast<int8_t>(encoded.encoding);
    msg.data.swap(encoded.data);
    msg.data_size = static_cast<int32_t>(msg.data.size());
    ctx_->bus.publish(params_.camera.image_channel, msg);
    msg.data.swap(encoded.data);  // both buffers stay allocated
  }
}

void CameraStage::onTimer(Utime now) {
  if (now < next_calibration_) return;
  ctx_->bus.publish(params_.camera.calibration_channel,
                    bus::calibrationMessage(params_.camera, now));
  next_calibration_ = now + fromSeconds(params_.calibration_period_s);
}

void CameraStage::collectHealth(bus::HealthReport& report) {
  const capture::CameraCounters c = camera_->counters();
  const capture::SourceState state = camera_->state();
  report.add("frames", static_cast<double>(c.frames - last_counters_.frames), "count");
  report.add("frames_total", static_cast<double>(c.frames), "count");
  report.add("dropped_stale", static_cast<double>(c.dropped_stale), "count");
  report.add("dropped_rate", static_cast<double>(c.dropped_rate), "count");
  report.add("dropped_turn", static_cast<double>(c.dropped_turn), "count");
  report.add("dropped_size", static_cast<double>(wrong_size_.load()), "count");
  report.add("read_errors", static_cast<double>(c.read_errors), "count");
  report.add("sources_lost", static_cast<double>(c.sources_lost), "count");
  report.add("reopen_attempts", static_cast<double>(c.reopen_attempts), "count");
  report.add("laps", static_cast<double>(c.laps), "count");
  report.add("source_open", state == capture::SourceState::kOpen ? 1 : 0, "bool");
  if (state == capture::SourceState::kReopening) {
    report.warn(params_.source.describe() + " lost (" + camera_->lastProblem() + "), reopening");
  } else if (c.read_errors > last_counters_.read_errors) {
    report.warn("read errors: " + camera_->lastProblem());
  }
  if (wrong_size_.load() > 0) report.warn("frames of the wrong size dropped");
  if (!refused_settings_.empty()) report.warn("device refused settings (see the log)");
  last_counters_ = c;
}

void CameraStage::stop() {
  if (camera_) camera_->stop();
  if (thread_.joinable()) thread_.join();
}

void registerCamera(bus::StageRegistry& registry) {
  registry.add("camera", [](const bus::StageSetup& setup) {
    CameraStageParams p = CameraStageParams::load(setup.params, setup.stack.robot);
    setup.params.requireAllKeysUsed();  // a misspelt key before a device or file is opened
    std::unique_ptr<capture::FrameSource> source;
    try {
      source = capture::openSource(p.source);
    } catch (const capture::SourceError& e) {
      throw setup.params.error(e.setting(), e.what());
    }
    // What the front-ends will get must be what the robot file calibrates.
    const bool resized = p.capture.width > 0;
    const cv::Size size =
        resized ? cv::Size(p.capture.width, p.capture.height) : source->nativeSize();
    if (size.width > 0 && (size.width != p.camera.width || size.height != p.camera.height)) {
      std::string hint;
      if (!resized && size.width * p.camera.height == size.height * p.camera.width) {
        hint = "; set width: " + std::to_string(p.camera.width) +
               " and height: " + std::to_string(p.camera.height) + " to resize";
      } else if (size.width * p.camera.height == size.height * p.camera.width) {
        const config::CameraConfig scaled =
            capture::rescaleIntrinsics(p.camera, size.width, size.height);
        hint = "; for " + sizeText(size.width, size.height) + " the calibration would be fx " +
               std::to_string(scaled.fx) + " fy " + std::to_string(scaled.fy) + " cx " +
               std::to_string(scaled.cx) + " cy " + std::to_string(scaled.cy);
      }
      throw setup.params.error(resized ? "width" : "source",
                               (resized ? "resized to " : "the source gives ") +
                                   sizeText(size.width, size.height) + ", but camera '" +
                                   p.camera.name + "' is calibrated for " +
                                   sizeText(p.camera.width, p.camera.height) + " (" +
                                   p.camera.calibration_file.string() + ")" + hint);
    }
    return std::make_unique<CameraStage>(std::move(p), std::move(source));
  });
}

}  // namespace vslam::stages
