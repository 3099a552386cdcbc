#pragma once
// Reads the trajectories to evaluate from an LCM log: the reference
// (vslam.ground_truth_pose_t), estimates (vslam.pose_estimate_t) and raw
// odometry (vslam.odometry_t, its cumulative pose), and the landmarks of the
// last map (vslam.map_t). The type of each channel is recognised by the LCM
// fingerprint of its messages, so any of the three pose types can be used in
// any role. Message utime (data time) is the pose time, in seconds.
//
// The log must be intact: bytes the LCM reader would skip, a cut or corrupt
// tail, or a message that does not decode are DataErrors naming the byte
// offset, event and channel.

#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "eval/evaluate.hpp"

namespace vslam::eval {

struct LogReadOptions {
  std::string ref_channel = "GROUND_TRUTH";
  // Explicit channels; each must be in the log. If both are empty, the
  // defaults are used: POSE_ESTIMATE (estimate) if present, and
  // POSE_ODOMETRY (odometry), or ODOMETRY if there is no POSE_ODOMETRY.
  std::vector<std::string> est_channels;
  std::vector<std::string> odom_channels;
  std::string map_channel = "MAP";  // optional; empty: no landmarks
};

inline const char* const kDefaultEstimateChannel = "POSE_ESTIMATE";
inline const char* const kDefaultPoseOdometryChannel = "POSE_ODOMETRY";
inline const char* const kDefaultOdometryChannel = "ODOMETRY";

struct LogContents {
  Trajectory reference;
  std::string reference_source;  // LCM type name
  std::vector<EstimateInput> estimates;
  std::vector<LandmarkPosition> landmarks;
  std::map<std::string, int64_t> channel_counts;  // events per channel in the log
};

LogContents readLogTrajectories(const std::filesystem::path& log, const LogReadOptions& options);

}  // namespace vslam::eval
