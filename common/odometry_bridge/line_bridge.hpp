#pragma once
// vslam-odometry-bridge's core: turns a line stream from a robot base into
// the cumulative odometry pose the stack consumes (vslam.odometry_t; the
// contract and the line formats are in docs/odometry.md). No LCM.
//
// Two line formats, fields separated by spaces or tabs, '#' starts a comment
// line, blank lines are skipped:
//   pose:   "t x y theta"              seconds, metres, radians (odometry frame)
//   ticks:  "t left_ticks right_ticks" seconds, cumulative encoder counts
//
// Every line is hostile until checked. A line is rejected (counted by reason,
// nothing published) when it has the wrong number of fields, a field that is
// not a number, NaN or infinity, a count outside the counter's range, a time
// not after the last accepted one, or a step between it and the last accepted
// line larger than max_step_m / max_step_deg. The bridge never stops on a bad
// line. A source that restarts (its clock going back to zero, its counters or
// pose jumping) shows as a run of rejected lines that agree with each other;
// after resync_after of them the bridge takes the newest as its new reference
// and carries on from the pose it last published, so consumers see neither
// the jump nor a time going backwards.

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "odometry/pose2.hpp"
#include "odometry_bridge/wheel_odometry.hpp"
#include "util/time.hpp"

namespace vslam::odometry_bridge {

enum class LineFormat { kPose, kTicks };

// How a line's t becomes the message's utime (microseconds since the Unix epoch).
enum class TimestampMode {
  kRelative,  // t in the base's own clock (any origin): the first line maps to the
              // host's time at its arrival, later ones keep the base's spacing
  kAbsolute,  // t is Unix time in seconds (the base's clock is synchronized)
  kHost,      // the host's time at the line's arrival; t only orders lines
};

// "relative", "absolute", "host" (the config words) and back.
const char* timestampModeName(TimestampMode mode);
std::optional<TimestampMode> parseTimestampMode(std::string_view name);

struct BridgeParams {
  LineFormat format = LineFormat::kPose;
  TimestampMode timestamps = TimestampMode::kRelative;
  DiffDriveParams drive;     // kTicks only
  double max_step_m = 0.5;   // a larger step between two lines is a fault, not motion
  double max_step_deg = 45;  // likewise for rotation
  int resync_after = 3;      // consecutive agreeing rejected lines that mean the source restarted
};

// Throws std::invalid_argument naming the parameter (config keys use the same names).
void validate(const BridgeParams& params);

enum class Rejection {
  kFieldCount,         // wrong number of fields
  kNotANumber,         // a field is not a number (or a count not an integer)
  kNonFinite,          // NaN or infinity
  kTickRange,          // a count the configured counter cannot hold
  kTimeNotIncreasing,  // t not after the last accepted line's
  kTimeOutOfRange,     // absolute timestamps: t is not a plausible Unix time
  kJump,               // step above max_step_m / max_step_deg
  kTooLong,            // longer than kMaxLineLength
};
inline constexpr size_t kNumRejections = 8;
inline constexpr size_t kMaxLineLength = 256;  // bytes; a longer line is not a reading
const char* describe(Rejection reason);
// Short name for health metrics, e.g. "field_count".
const char* metricName(Rejection reason);

// One published reading (the fields of vslam.odometry_t).
struct OdometryOutput {
  Utime utime = 0;
  int64_t seq = 0;
  Pose2 pose;           // cumulative, odometry frame
  double distance = 0;  // cumulative path length, m
  double rotation = 0;  // cumulative absolute rotation, rad
  double v = 0;         // m/s over the last step
  double omega = 0;     // rad/s over the last step
};

struct LineResult {
  enum class Kind { kOutput, kRejected, kSkipped };  // kSkipped: blank or comment
  Kind kind = Kind::kSkipped;
  OdometryOutput output;  // kOutput
  bool resynced = false;  // kOutput: the source restarted; this line is the new reference
  Rejection reason = Rejection::kFieldCount;  // kRejected
  std::string detail;                         // kRejected: what exactly was wrong
};

struct BridgeCounters {
  int64_t lines = 0;  // every line read, skipped ones included
  int64_t accepted = 0;
  int64_t rejected = 0;
  std::array<int64_t, kNumRejections> rejected_by_reason{};
  int64_t resyncs = 0;
  Utime last_line_host_utime = 0;  // host time of the last line read
  Utime last_output_utime = 0;     // utime of the last published reading
};

class LineBridge {
 public:
  explicit LineBridge(BridgeParams params);  // throws std::invalid_argument (validate)

  // One line without its newline; host_utime: the host's wall clock at its arrival.
  LineResult addLine(std::string_view line, Utime host_utime);
  const BridgeCounters& counters() const { return counters_; }
  const BridgeParams& params() const { return params_; }

 private:
  struct Sample {
    double t = 0;
    Pose2 pose;                   // kPose
    int64_t left = 0, right = 0;  // kTicks
  };
  LineResult reject(Rejection reason, std::string detail);
  // The sample parsed from the fields, or a rejection.
  std::optional<LineResult> parse(std::string_view line, Sample* sample) const;
  // Motion from `from` to `to` in from's frame, ignoring the rebase.
  Pose2 stepBetween(const Sample& from, const Sample& to) const;
  std::optional<std::string> implausibleStep(const Pose2& step) const;
  // Rejected lines that may be a restarted source: kept while they agree.
  void noteCandidate(const Sample& sample);
  LineResult emit(const Sample& sample, const Pose2& step, Utime utime, bool resynced);
  Utime utimeOf(const Sample& sample, Utime host_utime) const;

  BridgeParams params_;
  BridgeCounters counters_;
  std::optional<Sample> last_;  // last accepted line
  Pose2 pose_;                  // published cumulative pose
  Pose2 rebase_;                // kPose: published = rebase_ (+) line pose
  double distance_ = 0, rotation_ = 0;
  Utime last_utime_ = 0;
  int64_t seq_ = 0;
  // kRelative: utime = origin_utime_ + (t - origin_t_).
  Utime origin_utime_ = 0;
  double origin_t_ = 0;
  std::vector<Sample> candidates_;
};

}  // namespace vslam::odometry_bridge
