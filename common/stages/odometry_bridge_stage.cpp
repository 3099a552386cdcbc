#include "stages/odometry_bridge_stage.hpp"

#include <vslam/odometry_t.hpp>

namespace vslam::stages {

using odometry_bridge::LineFormat;
using odometry_bridge::LineResult;
using odometry_bridge::LineSource;
using odometry_bridge::SourceKind;

const config::ParamTable<OdometryBridgeParams>& OdometryBridgeParams::table() {
  using P = OdometryBridgeParams;
  using config::InRange;
  using odometry_bridge::TimestampMode;
  static const config::ParamTable<P> declared = [] {
    config::ParamTable<P> t;
    // Keys of the other sources and formats may stay in the block (switching
    // is one edit); the chosen one's own are checked below.
    t.choice(
         "source", [](auto& p) -> auto& { return p.source.kind; },
         std::vector<std::pair<std::string, SourceKind>>{{"stdin", SourceKind::kStdin},
                                                         {"serial", SourceKind::kSerial},
                                                         {"udp", SourceKind::kUdp}},
         "where the lines come from")
        .required()
        .add(
            "serial_device", [](auto& p) -> auto& { return p.source.serial_device; },
            "device path (required for `serial`)")
        .add(
            "baud", [](auto& p) -> auto& { return p.source.baud; }, InRange{1, 4000000}, "",
            "serial rate")
        .add(
            "udp_port", [](auto& p) -> auto& { return p.source.udp_port; }, InRange{0, 65535}, "",
            "port on 127.0.0.1 (required for `udp`)")
        .choice(
            "format", [](auto& p) -> auto& { return p.bridge.format; },
            std::vector<std::pair<std::string, LineFormat>>{{"pose", LineFormat::kPose},
                                                            {"ticks", LineFormat::kTicks}},
            "`pose`: t x y theta; `ticks`: t left_ticks right_ticks")
        .required()
        .choice(
            "timestamps", [](auto& p) -> auto& { return p.bridge.timestamps; },
            std::vector<std::pair<std::string, TimestampMode>>{
                {"relative", TimestampMode::kRelative},
                {"absolute", TimestampMode::kAbsolute},
                {"host", TimestampMode::kHost}},
            "how a line's t becomes the message's time (above)")
        .add(
            "ticks_per_rev", [](auto& p) -> auto& { return p.bridge.drive.ticks_per_rev; },
            config::nonNegative(), "ticks",
            "encoder ticks per wheel revolution (required for `ticks`)")
        .add(
            "wheel_radius_m", [](auto& p) -> auto& { return p.bridge.drive.wheel_radius_m; },
            config::nonNegative(), "m", "wheel radius (required for `ticks`)")
        .add(
            "track_width_m", [](auto& p) -> auto& { return p.bridge.drive.track_width_m; },
            config::nonNegative(), "m", "distance between the wheels (required for `ticks`)")
        .add(
            "counter_bits", [](auto& p) -> auto& { return p.bridge.drive.counter_bits; },
            InRange{odometry_bridge::kMinCounterBits, odometry_bridge::kMaxCounterBits}, "bits",
            "encoder counter width")
        .add(
            "max_step_m", [](auto& p) -> auto& { return p.bridge.max_step_m; }, config::positive(),
            "m", "larger steps between lines are rejected")
        .add(
            "max_step_deg", [](auto& p) -> auto& { return p.bridge.max_step_deg; },
            InRange{1e-3, 180}, "deg", "likewise for rotation")
        .add(
            "resync_after", [](auto& p) -> auto& { return p.bridge.resync_after; },
            InRange{2, 1000}, "lines", "agreeing rejected lines that mean the source restarted")
        .add("line_timeout_s", &P::line_timeout_s, InRange{0.01, 3600}, "s",
             "health warns after this long without a line")
        .add("reopen_period_s", &P::reopen_period_s, InRange{0.01, 3600}, "s",
             "a serial device that went away is retried this often")
        .check([](const config::ConfigNode& node, const P& p) {
          if (!odometry_bridge::isSupportedBaud(p.source.baud)) {
            throw node.error("baud", "unsupported rate " + std::to_string(p.source.baud) +
                                         "; one of 9600 19200 38400 57600 115200 230400 460800 "
                                         "921600");
          }
          if (p.source.kind == SourceKind::kSerial && p.source.serial_device.empty()) {
            throw node.error("serial_device",
                             "missing (source: serial needs the device, e.g. /dev/ttyUSB0)");
          }
          if (p.source.kind == SourceKind::kUdp && p.source.udp_port == 0) {
            throw node.error("udp_port", "missing (source: udp needs a port in 1..65535)");
          }
          if (p.bridge.format != LineFormat::kTicks) return;
          const auto& drive = p.bridge.drive;
          for (const auto& [key, value] :
               {std::pair<const char*, double>{"ticks_per_rev", drive.ticks_per_rev},
                {"wheel_radius_m", drive.wheel_radius_m},
                {"track_width_m", drive.track_width_m}}) {
            if (!(value > 0)) throw node.error(key, "format: ticks needs it > 0");
          }
        });
    return t;
  }();
  return declared;
}

OdometryBridgeParams OdometryBridgeParams::load(const config::ConfigNode& node,
                                                const config::RobotConfig& robot) {
  OdometryBridgeParams p;
  table().load(node, p);
  p.odometry_channel = robot.channels.odometry;
  return p;
}

OdometryBridgeStage::OdometryBridgeStage(OdometryBridgeParams params,
                                         const config::ConfigNode& node)
    : params_(std::move(params)), bridge_(params_.bridge) {
  try {
    source_ = std::make_unique<LineSource>(params_.source);
  } catch (const std::exception& e) {
    throw node.error(params_.source.kind == SourceKind::kUdp ? "udp_port" : "serial_device",
                     e.what());
  }
}

OdometryBridgeStage::~OdometryBridgeStage() { stop(); }

void OdometryBridgeStage::start(bus::StageContext& ctx) {
  ctx_ = &ctx;
  log::info("reading odometry lines (",
            params_.bridge.format == LineFormat::kPose ? "t x y theta" : "t left_ticks right_ticks",
            ") from ", source_->describe(), ", publishing on ", params_.odometry_channel);
  reader_ = std::thread([this] { readLoop(); });
}

void OdometryBridgeStage::stop() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
  }
  stop_cv_.notify_all();
  if (reader_.joinable()) reader_.join();
}

bool OdometryBridgeStage::waitOrStop(double seconds) {
  std::unique_lock<std::mutex> lock(mutex_);
  return !stop_cv_.wait_for(lock, std::chrono::duration<double>(seconds),
                            [this] { return stopping_; });
}

void OdometryBridgeStage::readLoop() {
  constexpr int kPollMs = 100;  // how soon a stop request is seen
  std::string line;
  while (true) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (stopping_) return;
    }
    LineSource::Status status = LineSource::Status::kClosed;
    try {
      status = source_->next(&line, kPollMs, odometry_bridge::kMaxLineLength);
    } catch (const std::exception& e) {
      log::error("reading ", source_->describe(), ": ", e.what());
    }
    if (status == LineSource::Status::kLine) {
      handleLine(line);
      continue;
    }
    if (status == LineSource::Status::kTimeout) continue;

    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (source_open_) log::warn(source_->describe(), " closed; no more odometry from it");
      source_open_ = false;
    }
    if (params_.source.kind != SourceKind::kSerial) {
      // stdin at EOF stays closed; keep reporting health until stopped.
      if (!waitOrStop(3600)) return;
      continue;
    }
    // A serial adapter unplugged: try again until it is back.
    while (waitOrStop(params_.reopen_period_s)) {
      try {
        source_->reopen();
        log::info(source_->describe(), " open again");
        std::lock_guard<std::mutex> lock(mutex_);
        source_open_ = true;
        break;
      } catch (const std::exception& e) {
        log::debug("reopen failed: ", e.what());
      }
    }
  }
}

void OdometryBridgeStage::handleLine(const std::string& line) {
  LineResult r;
  int64_t line_number = 0, rejected = 0;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    r = bridge_.addLine(line, ctx_->clock.now());
    line_number = bridge_.counters().lines;
    rejected = bridge_.counters().rejected;
    if (r.kind == LineResult::Kind::kRejected) {
      ++period_rejected_;
      constexpr size_t kShown = 80;  // of the offending line, in the warning
      const std::string shown = line.size() > kShown ? line.substr(0, kShown) + "..." : line;
      warnings_.warn(static_cast<size_t>(r.reason), monotonicUtime(), "odometry line ", line_number,
                     " '", shown, "' rejected: ", odometry_bridge::describe(r.reason), ": ",
                     r.detail, " (", rejected, " rejected so far)");
    }
  }
  if (r.kind != LineResult::Kind::kOutput) return;
  if (r.resynced) {
    log::warn("odometry line ", line_number,
              ": the source restarted (its time or pose jumped and stayed); continuing from the "
              "last published pose");
  }
  vslam::odometry_t msg{};
  msg.utime = r.output.utime;
  msg.seq = r.output.seq;
  msg.x = r.output.pose.x;
  msg.y = r.output.pose.y;
  msg.theta = r.output.pose.theta;
  msg.distance = r.output.distance;
  msg.rotation = r.output.rotation;
  msg.v = r.output.v;
  msg.omega = r.output.omega;
  ctx_->bus.publish(params_.odometry_channel, msg);
}

void OdometryBridgeStage::collectHealth(bus::HealthReport& report) {
  std::lock_guard<std::mutex> lock(mutex_);
  const odometry_bridge::BridgeCounters& c = bridge_.counters();
  report.add("lines_read", static_cast<double>(c.lines), "count");
  report.add("lines_accepted", static_cast<double>(c.accepted), "count");
  report.add("lines_rejected", static_cast<double>(c.rejected), "count");
  for (size_t i = 0; i < odometry_bridge::kNumRejections; ++i) {
    if (c.rejected_by_reason[i] == 0) continue;
    report.add(std::string("rejected_") +
                   odometry_bridge::metricName(static_cast<odometry_bridge::Rejection>(i)),
               static_cast<double>(c.rejected_by_reason[i]), "count");
  }
  report.add("resyncs", static_cast<double>(c.resyncs), "count");
  report.add("source_open", source_open_ ? 1.0 : 0.0);
  const Utime now = ctx_ ? ctx_->clock.now() : 0;
  if (c.last_line_host_utime > 0) {
    const double age_s = toSeconds(now - c.last_line_host_utime);
    report.add("last_line_age_s", age_s, "s");
    report.add("last_line_time_s", toSeconds(c.last_line_host_utime), "s");
    if (age_s > params_.line_timeout_s) {
      report.warn("no line from " + source_->describe() + " for " + std::to_string(age_s) + " s");
    }
  } else {
    report.warn("no line yet from " + source_->describe());
  }
  if (!source_open_) report.warn(source_->describe() + " closed");
  if (period_rejected_ > 0) {
    report.warn(std::to_string(period_rejected_) + " lines rejected in the last period");
  }
  period_rejected_ = 0;
}

void registerOdometryBridge(bus::StageRegistry& registry) {
  registry.add(
      "odometry_bridge",
      [](const bus::StageSetup& setup) {
        return std::make_unique<OdometryBridgeStage>(
            OdometryBridgeParams::load(setup.params, setup.stack.robot), setup.params);
      },
      bus::describeWith(OdometryBridgeParams::table()));
}

}  // namespace vslam::stages
