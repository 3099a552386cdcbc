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
config::ParamTable<capture::V4l2Settings> v4l2Table() {
  using V = capture::V4l2Settings;
  using config::InRange;
  config::ParamTable<V> t;
  t.add("width", &V::width, InRange{0, 16384}, "px",
        "capture mode asked of the device (`v4l2-ctl --list-formats-ext` lists them); 0: the "
        "device's")
      .add("height", &V::height, InRange{0, 16384}, "px", "the same")
      .add("fps", &V::fps, InRange{0, 1000}, "Hz", "the same; 0: the device's")
      .add("fourcc", &V::fourcc, "pixel format, e.g. MJPG, YUYV; \"\": the device's")
      .add("auto_exposure", &V::auto_exposure, "control; unset: as the device is")
      .add("exposure", &V::exposure, config::nonNegative(), "device units",
           "control (V4L2 exposure_absolute: 100 µs); unset: as the device is")
      .add("gain", &V::gain, config::nonNegative(), "device units",
           "control; unset: as the device is")
      .check([](const config::ConfigNode& node, const V& v) {
        if (!v.fourcc.empty() && v.fourcc.size() != 4) {
          throw node.error("fourcc", "'" + v.fourcc + "' is not a four-character code (e.g. MJPG)");
        }
      });
  return t;
}

}  // namespace

const config::ParamTable<CameraStageParams>& CameraStageParams::table() {
  using P = CameraStageParams;
  using capture::PixelEncoding;
  using config::InRange;
  static const config::ParamTable<P> declared = [] {
    config::ParamTable<P> t;
    t.add("camera", &P::camera_name, "the robot file's camera (size, calibration, channels)")
        .required()
        .add("source", &P::source_text,
             "`v4l2:DEVICE`, `gstreamer:PIPELINE`, `video:FILE` or `folder:DIR` (docs/camera.md, "
             "Sources); a relative file is taken from the config file's directory")
        .required()
        .block(
            "v4l2", [](auto& p) -> auto& { return p.source.v4l2; }, v4l2Table())
        .choice("encoding", &P::encoding,
                std::vector<std::pair<std::string, PixelEncoding>>{{"gray8", PixelEncoding::kGray8},
                                                                   {"bgr8", PixelEncoding::kBgr8},
                                                                   {"jpeg", PixelEncoding::kJpeg}},
                "`vslam.image_t` encoding (the bus load depends on it)")
        .required()
        .add("jpeg_quality", &P::jpeg_quality, InRange{1, 100}, "", "for encoding jpeg")
        .add(
            "width", [](auto& p) -> auto& { return p.capture.width; }, InRange{0, 16384}, "px",
            "resize to this (width and height both or neither); 0: the source's size")
        .add(
            "height", [](auto& p) -> auto& { return p.capture.height; }, InRange{0, 16384}, "px",
            "the same")
        .add(
            "max_fps", [](auto& p) -> auto& { return p.capture.max_fps; }, InRange{0, 1000}, "Hz",
            "frames closer than 0.9 / max_fps to the previous one are dropped (`dropped_rate`); "
            "0: none")
        .custom(
            "alternate", "",
            "`{slot: K, slots: N}`: take turns with N - 1 other cameras, one frame per N / "
            "`max_fps` period, in slot K (docs/camera.md, Alternating acquisition; needs "
            "`max_fps`)",
            [](const config::ConfigNode& node, const std::string& key, P& p) {
              if (node.has(key) && p.capture.max_fps <= 0) {
                throw node.error(key,
                                 "needs max_fps > 0: the cameras taking turns share that rate");
              }
              p.capture.alternate = config::readAlternation(node, key, p.capture.max_fps);
            },
            [](const P& p) {
              const Alternation& a = p.capture.alternate;
              return a.active() ? "{slot: " + std::to_string(a.slot) +
                                      ", slots: " + std::to_string(a.slots) + "}"
                                : std::string("none");
            })
        .add(
            "speed", [](auto& p) -> auto& { return p.capture.speed; }, InRange{0, 1000}, "x",
            "recordings only: multiple of real time; 0: as fast as they decode")
        .add(
            "loop", [](auto& p) -> auto& { return p.capture.loop; },
            "recordings only: start again at the end")
        .add(
            "reopen_initial_s", [](auto& p) -> auto& { return p.capture.reopen_initial_s; },
            InRange{0.001, 60}, "s", "first wait before reopening a lost source...")
        .add(
            "reopen_max_s", [](auto& p) -> auto& { return p.capture.reopen_max_s; },
            InRange{0.001, 3600}, "s", "...doubling up to this")
        .add(
            "max_consecutive_errors",
            [](auto& p) -> auto& { return p.capture.max_consecutive_errors; }, InRange{1, 1000}, "",
            "read errors in a row that mean the source is gone")
        .add("calibration_period_s", &P::calibration_period_s, InRange{0.1, 60}, "s",
             "between calibration messages")
        .check([](const config::ConfigNode& node, const P& p) {
          const capture::CameraParams& c = p.capture;
          if ((c.width == 0) != (c.height == 0)) {
            throw node.error(c.width == 0 ? "width" : "height",
                             "give both width and height, or neither");
          }
        });
    return t;
  }();
  return declared;
}

CameraStageParams CameraStageParams::load(const config::ConfigNode& node,
                                          const config::RobotConfig& robot) {
  CameraStageParams p;
  table().load(node, p);
  try {
    p.camera = robot.camera(p.camera_name);
  } catch (const std::out_of_range&) {
    std::string known;
    for (const auto& c : robot.cameras) known += (known.empty() ? "" : ", ") + c.name;
    throw node.error("camera", "no camera '" + p.camera_name + "' in " + robot.file.string() +
                                   " (it has: " + known + ")");
  }
  const capture::V4l2Settings v4l2 = p.source.v4l2;  // the block, read by the table
  try {
    p.source = capture::SourceSpec::parse(p.source_text);
  } catch (const capture::SourceError& e) {
    throw node.error("source", e.what());
  }
  p.source.v4l2 = v4l2;
  if (p.source.isReplay() && std::filesystem::path(p.source.location).is_relative()) {
    p.source.location = (node.baseDir() / p.source.location).lexically_normal().string();
  }
  if (node.has("v4l2") && p.source.kind != capture::SourceSpec::Kind::kV4l2) {
    throw node.error("v4l2", "device settings need a v4l2: source");
  }
  if (!p.source.isReplay()) {
    for (const char* key : {"speed", "loop"}) {
      if (node.has(key)) throw node.error(key, "only for video: and folder: sources");
    }
  }
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
  registry.add(
      "camera",
      [](const bus::StageSetup& setup) {
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
      },
      bus::describeWith(CameraStageParams::table()));
}

}  // namespace vslam::stages
