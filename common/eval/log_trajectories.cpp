#include "eval/log_trajectories.hpp"

#include <cstdio>
#include <lcm/lcm-cpp.hpp>
#include <optional>
#include <set>
#include <sstream>
#include <vslam/ground_truth_pose_t.hpp>
#include <vslam/map_t.hpp>
#include <vslam/odometry_t.hpp>
#include <vslam/pose_estimate_t.hpp>

#include "eval/errors.hpp"
#include "eval/log_events.hpp"
#include "util/log.hpp"

namespace vslam::eval {
namespace {

enum class PoseType { kGroundTruth, kPoseEstimate, kOdometry };

std::optional<PoseType> poseTypeOf(int64_t hash) {
  if (hash == vslam::ground_truth_pose_t::getHash()) return PoseType::kGroundTruth;
  if (hash == vslam::pose_estimate_t::getHash()) return PoseType::kPoseEstimate;
  if (hash == vslam::odometry_t::getHash()) return PoseType::kOdometry;
  return std::nullopt;
}

std::string typeName(PoseType t) {
  switch (t) {
    case PoseType::kGroundTruth:
      return "vslam.ground_truth_pose_t";
    case PoseType::kPoseEstimate:
      return "vslam.pose_estimate_t";
    case PoseType::kOdometry:
      return "vslam.odometry_t";
  }
  return "?";
}

struct ChannelTrajectory {
  Trajectory traj;
  std::optional<PoseType> type;
};

}  // namespace

LogContents readLogTrajectories(const std::filesystem::path& log, const LogReadOptions& options) {
  const std::string name = log.string();
  const bool use_defaults = options.est_channels.empty() && options.odom_channels.empty();

  std::set<std::string> pose_channels = {options.ref_channel};
  for (const auto& c : options.est_channels) pose_channels.insert(c);
  for (const auto& c : options.odom_channels) pose_channels.insert(c);
  if (use_defaults) {
    pose_channels.insert(kDefaultEstimateChannel);
    pose_channels.insert(kDefaultPoseOdometryChannel);
    pose_channels.insert(kDefaultOdometryChannel);
  }

  LogContents out;
  std::map<std::string, ChannelTrajectory> trajs;
  std::optional<vslam::map_t> last_map;
  out.channel_counts = forEachLogEvent(log, [&](const LogEventRef& ref) {
    const lcm::LogEvent* ev = &ref.event;
    const long event_offset = ref.offset;
    if (pose_channels.count(ev->channel)) {
      const int64_t hash = fingerprint(ev->data, ev->datalen);
      const auto type = poseTypeOf(hash);
      auto& ct = trajs[ev->channel];
      ct.traj.name = ev->channel;
      if (!type) {
        std::ostringstream os;
        os << name << ": channel " << ev->channel << " (event " << ev->eventnum << ", byte "
           << event_offset
           << ") carries a message that is not vslam.ground_truth_pose_t, vslam.pose_estimate_t "
              "or vslam.odometry_t";
        throw DataError(os.str());
      }
      if (ct.type && *ct.type != *type) {
        std::ostringstream os;
        os << name << ": channel " << ev->channel << " mixes " << typeName(*ct.type) << " and "
           << typeName(*type) << " (event " << ev->eventnum << ")";
        throw DataError(os.str());
      }
      ct.type = type;
      switch (*type) {
        case PoseType::kGroundTruth: {
          const auto m = decodeEvent<vslam::ground_truth_pose_t>(ref, typeName(*type));
          ct.traj.poses.push_back(planarPose(m.utime * 1e-6, m.x, m.y, m.z, m.theta));
          break;
        }
        case PoseType::kPoseEstimate: {
          const auto m = decodeEvent<vslam::pose_estimate_t>(ref, typeName(*type));
          ct.traj.poses.push_back(planarPose(m.utime * 1e-6, m.x, m.y, 0.0, m.theta));
          break;
        }
        case PoseType::kOdometry: {
          const auto m = decodeEvent<vslam::odometry_t>(ref, typeName(*type));
          ct.traj.poses.push_back(planarPose(m.utime * 1e-6, m.x, m.y, 0.0, m.theta));
          break;
        }
      }
    } else if (!options.map_channel.empty() && ev->channel == options.map_channel) {
      if (fingerprint(ev->data, ev->datalen) != vslam::map_t::getHash()) {
        std::ostringstream os;
        os << name << ": channel " << ev->channel << " (event " << ev->eventnum
           << ") is not vslam.map_t; choose the map channel with --map-channel";
        throw DataError(os.str());
      }
      last_map = decodeEvent<vslam::map_t>(ref, "vslam.map_t");
    }
  });
  auto take = [&](const std::string& channel, const std::string& role) -> ChannelTrajectory& {
    auto it = trajs.find(channel);
    if (it == trajs.end() || it->second.traj.empty()) {
      throw DataError(name + ": no messages on channel " + channel + " (" + role +
                      "); channels in the log: " + channelList(out.channel_counts));
    }
    const std::size_t dropped = sortByTime(&it->second.traj);
    if (dropped > 0) {
      log::warn(name, ": ", channel, ": ", dropped,
                " message(s) repeat an earlier utime; kept the last");
    }
    return it->second;
  };
  auto present = [&](const std::string& channel) { return trajs.count(channel) > 0; };

  auto& ref = take(options.ref_channel, "the reference, --ref-channel");
  out.reference = ref.traj;
  out.reference_source = typeName(*ref.type);

  auto addEstimate = [&](const std::string& channel, EstimateKind kind, const std::string& role) {
    auto& ct = take(channel, role);
    out.estimates.push_back({ct.traj, kind, typeName(*ct.type)});
  };
  if (use_defaults) {
    if (present(kDefaultEstimateChannel)) {
      addEstimate(kDefaultEstimateChannel, EstimateKind::kEstimate, "estimate");
    }
    if (present(kDefaultPoseOdometryChannel)) {
      addEstimate(kDefaultPoseOdometryChannel, EstimateKind::kOdometry, "odometry-only estimate");
    } else if (present(kDefaultOdometryChannel)) {
      addEstimate(kDefaultOdometryChannel, EstimateKind::kOdometry, "raw odometry");
    }
    if (out.estimates.empty()) {
      throw DataError(name + ": no estimate to evaluate: none of " +
                      std::string(kDefaultEstimateChannel) + ", " + kDefaultPoseOdometryChannel +
                      ", " + kDefaultOdometryChannel +
                      " is in the log (channels: " + channelList(out.channel_counts) +
                      "); name one with --est-channel or --odom-channel");
    }
  } else {
    for (const auto& c : options.est_channels) {
      addEstimate(c, EstimateKind::kEstimate, "--est-channel");
    }
    for (const auto& c : options.odom_channels) {
      addEstimate(c, EstimateKind::kOdometry, "--odom-channel");
    }
  }
  if (last_map) {
    for (const auto& l : last_map->landmarks) out.landmarks.push_back({l.landmark_id, l.x, l.y});
  }
  return out;
}

}  // namespace vslam::eval
