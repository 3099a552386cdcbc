#include "odometry_bridge/line_bridge.hpp"

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <sstream>
#include <stdexcept>

#include "util/angles.hpp"

namespace vslam::odometry_bridge {
namespace {

// Absolute timestamps outside 2000-2100 are not Unix time in seconds (a
// base sending milliseconds or seconds since boot, with timestamps: absolute).
constexpr double kMinUnixTime = 946684800.0;
constexpr double kMaxUnixTime = 4102444800.0;

std::vector<std::string> splitFields(std::string_view line) {
  std::vector<std::string> fields;
  size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t')) ++i;
    size_t j = i;
    while (j < line.size() && line[j] != ' ' && line[j] != '\t') ++j;
    if (j > i) fields.emplace_back(line.substr(i, j - i));
    i = j;
  }
  return fields;
}

bool parseDouble(const std::string& s, double* out) {
  errno = 0;
  char* end = nullptr;
  const double v = std::strtod(s.c_str(), &end);
  if (end == s.c_str() || *end != '\0') return false;
  *out = v;  // overflow gives +-inf, caught as non-finite
  return true;
}

bool parseInteger(const std::string& s, int64_t* out) {
  errno = 0;
  char* end = nullptr;
  const long long v = std::strtoll(s.c_str(), &end, 10);
  if (end == s.c_str() || *end != '\0' || errno == ERANGE) return false;
  *out = v;
  return true;
}

template <class... Args>
std::string text(const Args&... args) {
  std::ostringstream os;
  os.precision(10);
  (os << ... << args);
  return os.str();
}

}  // namespace

void validate(const BridgeParams& p) {
  auto require = [](bool ok, const char* key, const std::string& problem) {
    if (!ok) throw std::invalid_argument(std::string(key) + ": " + problem);
  };
  require(p.max_step_m > 0, "max_step_m", "must be > 0");
  require(p.max_step_deg > 0 && p.max_step_deg <= 180, "max_step_deg", "must be in (0, 180]");
  require(p.resync_after >= 2, "resync_after", "must be >= 2");
  if (p.format == LineFormat::kTicks) {
    require(p.drive.ticks_per_rev > 0, "ticks_per_rev", "must be > 0");
    require(p.drive.wheel_radius_m > 0, "wheel_radius_m", "must be > 0");
    require(p.drive.track_width_m > 0, "track_width_m", "must be > 0");
    require(p.drive.counter_bits >= kMinCounterBits && p.drive.counter_bits <= kMaxCounterBits,
            "counter_bits", "must be in 8..63");
  }
}

const char* timestampModeName(TimestampMode mode) {
  switch (mode) {
    case TimestampMode::kRelative:
      return "relative";
    case TimestampMode::kAbsolute:
      return "absolute";
    case TimestampMode::kHost:
      return "host";
  }
  return "?";
}

std::optional<TimestampMode> parseTimestampMode(std::string_view name) {
  for (auto mode : {TimestampMode::kRelative, TimestampMode::kAbsolute, TimestampMode::kHost}) {
    if (name == timestampModeName(mode)) return mode;
  }
  return std::nullopt;
}

const char* describe(Rejection reason) {
  switch (reason) {
    case Rejection::kFieldCount:
      return "wrong number of fields";
    case Rejection::kNotANumber:
      return "not a number";
    case Rejection::kNonFinite:
      return "NaN or infinity";
    case Rejection::kTickRange:
      return "count outside the encoder counter's range";
    case Rejection::kTimeNotIncreasing:
      return "time not after the last accepted line";
    case Rejection::kTimeOutOfRange:
      return "not a Unix time";
    case Rejection::kJump:
      return "implausible jump";
    case Rejection::kTooLong:
      return "line too long";
  }
  return "?";
}

const char* metricName(Rejection reason) {
  switch (reason) {
    case Rejection::kFieldCount:
      return "field_count";
    case Rejection::kNotANumber:
      return "not_a_number";
    case Rejection::kNonFinite:
      return "non_finite";
    case Rejection::kTickRange:
      return "tick_range";
    case Rejection::kTimeNotIncreasing:
      return "time_backwards";
    case Rejection::kTimeOutOfRange:
      return "time_out_of_range";
    case Rejection::kJump:
      return "jump";
    case Rejection::kTooLong:
      return "too_long";
  }
  return "unknown";
}

LineBridge::LineBridge(BridgeParams params) : params_(std::move(params)) { validate(params_); }

LineResult LineBridge::reject(Rejection reason, std::string detail) {
  ++counters_.rejected;
  ++counters_.rejected_by_reason[static_cast<size_t>(reason)];
  LineResult r;
  r.kind = LineResult::Kind::kRejected;
  r.reason = reason;
  r.detail = std::move(detail);
  return r;
}

std::optional<LineResult> LineBridge::parse(std::string_view line, Sample* sample) const {
  auto rejected = [](Rejection reason, std::string detail) {
    LineResult r;
    r.kind = LineResult::Kind::kRejected;
    r.reason = reason;
    r.detail = std::move(detail);
    return r;
  };
  const std::vector<std::string> f = splitFields(line);
  const bool pose = params_.format == LineFormat::kPose;
  const size_t expected = pose ? 4 : 3;
  if (f.size() != expected) {
    return rejected(Rejection::kFieldCount,
                    text(f.size(), f.size() == 1 ? " field" : " fields", ", expected ", expected,
                         pose ? " (t x y theta)" : " (t left_ticks right_ticks)"));
  }
  static const char* kPoseNames[] = {"t", "x", "y", "theta"};
  static const char* kTickNames[] = {"t", "left_ticks", "right_ticks"};
  double values[4] = {0, 0, 0, 0};
  int64_t counts[3] = {0, 0, 0};
  for (size_t i = 0; i < f.size(); ++i) {
    const char* name = pose ? kPoseNames[i] : kTickNames[i];
    if (pose || i == 0) {
      if (!parseDouble(f[i], &values[i])) {
        return rejected(Rejection::kNotANumber, text(name, " '", f[i], "' is not a number"));
      }
      if (!std::isfinite(values[i])) {
        return rejected(Rejection::kNonFinite, text(name, " is ", f[i]));
      }
    } else {
      if (!parseInteger(f[i], &counts[i])) {
        return rejected(Rejection::kNotANumber,
                        text(name, " '", f[i], "' is not an integer count"));
      }
      if (!tickInRange(counts[i], params_.drive.counter_bits)) {
        return rejected(Rejection::kTickRange, text(name, " ", counts[i], " does not fit a ",
                                                    params_.drive.counter_bits, "-bit counter"));
      }
    }
  }
  sample->t = values[0];
  if (params_.timestamps == TimestampMode::kAbsolute &&
      (sample->t < kMinUnixTime || sample->t > kMaxUnixTime)) {
    return rejected(Rejection::kTimeOutOfRange,
                    text("t ", f[0], " s is not a Unix time in seconds (timestamps: absolute)"));
  }
  if (pose) {
    sample->pose = {values[1], values[2], values[3]};
  } else {
    sample->left = counts[1];
    sample->right = counts[2];
  }
  return std::nullopt;
}

Pose2 LineBridge::stepBetween(const Sample& from, const Sample& to) const {
  if (params_.format == LineFormat::kPose) return from.pose.between(to.pose);
  const int bits = params_.drive.counter_bits;
  const double left = ticksToMetres(tickDifference(from.left, to.left, bits), params_.drive);
  const double right = ticksToMetres(tickDifference(from.right, to.right, bits), params_.drive);
  return diffDriveStep(left, right, params_.drive.track_width_m);
}

std::optional<std::string> LineBridge::implausibleStep(const Pose2& step) const {
  const double d = std::hypot(step.x, step.y);
  if (d > params_.max_step_m) {
    return text("step of ", d, " m since the last accepted line (max_step_m ", params_.max_step_m,
                ")");
  }
  if (std::abs(step.theta) > degToRad(params_.max_step_deg)) {
    return text("turn of ", radToDeg(std::abs(step.theta)),
                " deg since the last accepted line (max_step_deg ", params_.max_step_deg, ")");
  }
  return std::nullopt;
}

Utime LineBridge::utimeOf(const Sample& sample, Utime host_utime) const {
  switch (params_.timestamps) {
    case TimestampMode::kAbsolute:
      return static_cast<Utime>(std::llround(sample.t * 1e6));
    case TimestampMode::kRelative:
      return origin_utime_ + static_cast<Utime>(std::llround((sample.t - origin_t_) * 1e6));
    case TimestampMode::kHost:
      break;
  }
  return host_utime;
}

void LineBridge::noteCandidate(const Sample& sample) {
  if (!candidates_.empty()) {
    const Sample& prev = candidates_.back();
    if (sample.t <= prev.t || implausibleStep(stepBetween(prev, sample))) candidates_.clear();
  }
  candidates_.push_back(sample);
}

LineResult LineBridge::emit(const Sample& sample, const Pose2& step, Utime utime, bool resynced) {
  if (params_.format == LineFormat::kPose) {
    pose_ = rebase_.compose(sample.pose);
  } else {
    pose_ = pose_.compose(step);
  }
  distance_ += std::hypot(step.x, step.y);
  rotation_ += std::abs(step.theta);
  LineResult r;
  r.kind = LineResult::Kind::kOutput;
  r.resynced = resynced;
  OdometryOutput& o = r.output;
  o.utime = utime;
  o.seq = seq_++;
  o.pose = pose_;
  o.distance = distance_;
  o.rotation = rotation_;
  if (last_ && !resynced && utime > last_utime_) {
    const double dt = toSeconds(utime - last_utime_);
    o.v = step.x / dt;
    o.omega = step.theta / dt;
  }
  last_ = sample;
  last_utime_ = utime;
  candidates_.clear();
  ++counters_.accepted;
  counters_.last_output_utime = utime;
  return r;
}

LineResult LineBridge::addLine(std::string_view line, Utime host_utime) {
  ++counters_.lines;
  counters_.last_line_host_utime = host_utime;
  if (line.size() > kMaxLineLength) {
    return reject(Rejection::kTooLong, text(line.size(), " bytes (at most ", kMaxLineLength, ")"));
  }
  while (!line.empty() && (line.back() == '\r' || line.back() == ' ' || line.back() == '\t')) {
    line.remove_suffix(1);
  }
  while (!line.empty() && (line.front() == ' ' || line.front() == '\t')) line.remove_prefix(1);
  if (line.empty() || line.front() == '#') return LineResult{};

  Sample sample;
  if (auto bad = parse(line, &sample)) return reject(bad->reason, bad->detail);

  if (!last_) {
    origin_utime_ = host_utime;
    origin_t_ = sample.t;
    if (params_.format == LineFormat::kPose) rebase_ = Pose2{};
    return emit(sample, Pose2{}, utimeOf(sample, host_utime), false);
  }

  std::optional<LineResult> rejection;
  if (sample.t <= last_->t) {
    rejection = reject(Rejection::kTimeNotIncreasing,
                       text("t ", sample.t, " s is not after the last accepted ", last_->t, " s"));
    // A synchronized clock that went back cannot be followed without
    // publishing a time going backwards: no resync for absolute time.
    if (params_.timestamps == TimestampMode::kAbsolute) return *rejection;
  } else {
    const Pose2 step = stepBetween(*last_, sample);
    if (auto why = implausibleStep(step)) {
      rejection = reject(Rejection::kJump, *why);
    } else {
      Utime utime = utimeOf(sample, host_utime);
      if (utime <= last_utime_) utime = last_utime_ + 1;  // host clock granularity
      return emit(sample, step, utime, false);
    }
  }

  noteCandidate(sample);
  if (static_cast<int>(candidates_.size()) < params_.resync_after) return *rejection;
  // The source restarted: the newest agreeing line is the new reference, and
  // the published pose and time carry on from where they were.
  --counters_.rejected;
  --counters_.rejected_by_reason[static_cast<size_t>(rejection->reason)];
  ++counters_.resyncs;
  if (params_.format == LineFormat::kPose) rebase_ = pose_.compose(sample.pose.inverse());
  Utime utime = host_utime;
  if (params_.timestamps == TimestampMode::kRelative) {
    origin_utime_ = std::max(host_utime, last_utime_ + 1);
    origin_t_ = sample.t;
    utime = origin_utime_;
  } else if (params_.timestamps == TimestampMode::kAbsolute) {
    utime = utimeOf(sample, host_utime);
  }
  if (utime <= last_utime_) utime = last_utime_ + 1;
  return emit(sample, Pose2{}, utime, true);
}

}  // namespace vslam::odometry_bridge
